//! The server's own memory for reading meshes: a budget in bytes (`server.asset_check_memory_bytes`) that
//! every read of a mesh inside the server process — an upload checked on arrival, the assets of a job
//! checked and costed at submission — holds for as long as the bytes and the parsed mesh live.
//!
//! A read of a mesh file of `n` bytes is charged `n · (1 + F)` bytes: the file itself (the upload's body,
//! or the asset loaded from the database) and `F · n` for the parsed mesh and its checks (vertex welding,
//! the half-edge structure of the manifold check). `F` ([`PARSED_BYTES_PER_FILE_BYTE`]) is an upper bound
//! measured per format: a text OBJ spends about 70 bytes of file per vertex, binary PLY and glTF about 36;
//! the parsed mesh and the checks about 400 bytes per vertex at their peak (docs/BENCHMARKS.md, "Server
//! memory"). The charge is known before anything is read — from the upload's `Content-Length` (the limit
//! `server.max_asset_bytes` when it is not sent) or the asset's stored size — so a request waits for its
//! share before it reads a byte.
//!
//! A request waits at most `server.asset_check_wait_s` for its share, and is then answered 429 with
//! `Retry-After` (the budget is the whole server's: 503 would make a load balancer take the node out). A
//! read whose charge alone exceeds the whole budget could never run: it is answered 422 naming the input
//! (the upload's `body`, or the spec field naming the asset), with the charge and the key to raise.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// Bytes of parsed mesh and check structures per byte of mesh file, by format (an upper bound; see the
/// module documentation).
pub fn parsed_bytes_per_file_byte(format: &str) -> u64 {
    match format {
        // Text: ~70 bytes of file per vertex.
        "obj" => 8,
        // Binary STL: 50 bytes per triangle, two triangles per vertex.
        "stl" => 6,
        // Binary PLY and glTF: ~36 bytes per vertex (ASCII PLY is larger, so this bounds it too).
        _ => 14,
    }
}

/// The largest factor of [`parsed_bytes_per_file_byte`], for a read whose format is not known yet.
pub const PARSED_BYTES_PER_FILE_BYTE: u64 = 14;

/// The budget's unit: permits are KiB (a tokio semaphore takes at most `u32::MAX` permits at once).
const UNIT: u64 = 1024;

/// Why a share of the budget was not granted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BudgetRefusal {
    /// The charge alone exceeds the whole budget.
    TooLarge { charge: u64, budget: u64 },
    /// The budget stayed taken for the whole wait.
    Busy { waited_s: u64 },
}

/// The server-wide byte budget of mesh reads.
#[derive(Debug, Clone)]
pub struct AssetBudget {
    slots: Arc<Semaphore>,
    units: u64,
    wait: Duration,
    in_use: Arc<AtomicU64>,
    peak: Arc<AtomicU64>,
}

/// A granted share; returned to the budget when dropped.
#[derive(Debug)]
pub struct BudgetShare {
    _permit: OwnedSemaphorePermit,
    bytes: u64,
    in_use: Arc<AtomicU64>,
}

impl Drop for BudgetShare {
    fn drop(&mut self) {
        self.in_use.fetch_sub(self.bytes, Ordering::SeqCst);
    }
}

impl AssetBudget {
    /// A budget of `bytes` (at least 1 KiB) whose requests wait at most `wait`.
    pub fn new(bytes: u64, wait: Duration) -> AssetBudget {
        let units = (bytes / UNIT).clamp(1, u64::from(u32::MAX));
        AssetBudget {
            slots: Arc::new(Semaphore::new(units as usize)),
            units,
            wait,
            in_use: Arc::new(AtomicU64::new(0)),
            peak: Arc::new(AtomicU64::new(0)),
        }
    }

    /// The charge of reading a mesh file of `file_bytes` bytes of `format` (`None`: not known yet).
    pub fn charge(file_bytes: u64, format: Option<&str>) -> u64 {
        let factor = format.map_or(PARSED_BYTES_PER_FILE_BYTE, parsed_bytes_per_file_byte);
        file_bytes.saturating_mul(1 + factor)
    }

    /// The whole budget, bytes.
    pub fn bytes(&self) -> u64 {
        self.units * UNIT
    }

    /// Bytes held by granted shares now.
    pub fn in_use(&self) -> u64 {
        self.in_use.load(Ordering::SeqCst)
    }

    /// The most bytes held at once since the server started.
    pub fn peak(&self) -> u64 {
        self.peak.load(Ordering::SeqCst)
    }

    /// Waits (at most the configured wait) for a share of `charge` bytes.
    pub async fn acquire(&self, charge: u64) -> Result<BudgetShare, BudgetRefusal> {
        let units = charge.div_ceil(UNIT).max(1);
        if units > self.units {
            return Err(BudgetRefusal::TooLarge {
                charge,
                budget: self.bytes(),
            });
        }
        let permit = tokio::time::timeout(
            self.wait,
            self.slots.clone().acquire_many_owned(units as u32),
        )
        .await
        .map_err(|_| BudgetRefusal::Busy {
            waited_s: self.wait.as_secs(),
        })?
        .map_err(|_| BudgetRefusal::Busy { waited_s: 0 })?;
        let bytes = units * UNIT;
        let now = self.in_use.fetch_add(bytes, Ordering::SeqCst) + bytes;
        self.peak.fetch_max(now, Ordering::SeqCst);
        Ok(BudgetShare {
            _permit: permit,
            bytes,
            in_use: self.in_use.clone(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn shares_wait_for_each_other_and_are_refused_beyond_the_budget() {
        let budget = AssetBudget::new(10 * 1024, Duration::from_millis(50));
        let a = budget.acquire(6 * 1024).await.unwrap();
        assert_eq!(budget.in_use(), 6 * 1024);
        // 6 + 6 KiB > 10 KiB: the second waits, then is refused as busy.
        assert_eq!(
            budget.acquire(6 * 1024).await.unwrap_err(),
            BudgetRefusal::Busy { waited_s: 0 }
        );
        drop(a);
        assert_eq!(budget.in_use(), 0);
        let _b = budget.acquire(6 * 1024).await.unwrap();
        assert_eq!(budget.peak(), 6 * 1024);
        assert!(matches!(
            budget.acquire(11 * 1024).await,
            Err(BudgetRefusal::TooLarge { .. })
        ));
    }

    #[test]
    fn the_charge_counts_the_file_and_its_parse() {
        assert_eq!(AssetBudget::charge(1000, Some("obj")), 9000);
        assert_eq!(
            AssetBudget::charge(1000, None),
            1000 * (1 + PARSED_BYTES_PER_FILE_BYTE)
        );
        assert_eq!(AssetBudget::charge(u64::MAX, None), u64::MAX);
    }
}
