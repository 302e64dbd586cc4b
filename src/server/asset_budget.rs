//! The server's own memory for reading meshes: a budget in bytes (`server.asset_check_memory_bytes`) that
//! every read of a mesh inside the server process — an upload checked on arrival, the assets of a job
//! checked and costed at submission — holds for as long as the bytes and the parsed mesh live.
//!
//! A read is charged in two steps, each before the memory it pays for is taken:
//!
//! 1. **the file**, `n` bytes ([`FILE_COPIES`] times: the body or the loaded asset, and the copies the
//!    database driver and SQLite make of the blob), before a byte of it is read: an upload's declared
//!    `Content-Length` (the limit `server.max_asset_bytes` when it declares none), an asset's stored size;
//! 2. **the parsed mesh and its checks**, [`BYTES_PER_ELEMENT`] per element (vertex or face) of the file,
//!    counted without parsing it by [`mesh_elements`]: the lines of a text file (each vertex and each face
//!    takes one), the triangle count of a binary STL, the element counts of a PLY header, the accessor
//!    counts of a glTF's JSON chunk. So a file of short lines — the most elements per byte — is charged
//!    for what it really costs, which a charge per byte would miss.
//!
//! The cost per element is measured (docs/BENCHMARKS.md, "Server memory"): a closed sphere of 163 842
//! vertices and 327 680 faces as a 17 MB OBJ, read to check it as a body surface and read again to cost the
//! job, raised the process's peak resident memory by 163 MB, about 300 bytes per element beyond the file;
//! the charge allows 400.
//!
//! The two charges come from two parts of the budget, a quarter for the files and the rest for their
//! parses (see [`AssetBudget`] for why).
//!
//! A request waits at most `server.asset_check_wait_s` for each share, and is then answered 429 with
//! `Retry-After` (the budget is the whole server's: 503 would make a load balancer take the node out). A
//! read whose charge alone exceeds the whole budget could never run: it is answered 422 naming the input
//! (the upload's `body`, or the spec field naming the asset), with the charge and the key to raise.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// Bytes of parsed mesh and check structures charged per element (vertex or face) of a mesh file.
pub const BYTES_PER_ELEMENT: u64 = 400;

/// Copies of a file's bytes charged while it is read: the request body or the loaded asset, and the
/// database driver's and SQLite's own copies of the blob as it is written or read.
pub const FILE_COPIES: u64 = 3;

/// An upper bound of the elements (vertices and faces) of a mesh file of `format`, counted without parsing
/// it (see the module documentation). A file whose counts cannot be read this way is bounded by its
/// length: no element takes fewer than 3 bytes in any of the formats.
pub fn mesh_elements(bytes: &[u8], format: &str) -> u64 {
    let len = bytes.len() as u64;
    let lines = || bytes.iter().filter(|&&b| b == b'\n').count() as u64 + 1;
    let by_length = len / 3 + 1;
    match format {
        "obj" => lines(),
        "stl" => {
            let binary = bytes
                .get(80..84)
                .map(|c| u64::from(u32::from_le_bytes([c[0], c[1], c[2], c[3]])))
                .filter(|n| 84 + 50 * n == len);
            // A binary STL's triangles and up to three vertices each; an ASCII one, its lines.
            binary.map_or_else(lines, |n| 4 * n)
        }
        "ply" => ply_elements(bytes).unwrap_or(by_length),
        "glb" => glb_elements(bytes).unwrap_or(by_length),
        _ => by_length,
    }
}

/// The sum of the element counts a PLY header declares.
fn ply_elements(bytes: &[u8]) -> Option<u64> {
    let end = bytes.windows(10).position(|w| w == b"end_header")?;
    let header = std::str::from_utf8(&bytes[..end]).ok()?;
    let mut total = 0u64;
    for line in header.lines() {
        let mut words = line.split_whitespace();
        if words.next() == Some("element") {
            let count: u64 = words.nth(1)?.parse().ok()?;
            total = total.saturating_add(count);
        }
    }
    Some(total)
}

/// The sum of the accessor counts of a binary glTF's JSON chunk (positions, indices, …: at least its
/// vertices and faces).
fn glb_elements(bytes: &[u8]) -> Option<u64> {
    let word = |at: usize| -> Option<usize> {
        let c = bytes.get(at..at + 4)?;
        Some(u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as usize)
    };
    if bytes.get(..4)? != b"glTF" || bytes.get(16..20)? != b"JSON" {
        return None;
    }
    let json = bytes.get(20..20usize.checked_add(word(12)?)?)?;
    let doc: serde_json::Value = serde_json::from_slice(json).ok()?;
    let mut total = 0u64;
    for a in doc.get("accessors")?.as_array()? {
        total = total.saturating_add(a.get("count")?.as_u64()?);
    }
    Some(total)
}

/// Hands the memory freed by a read back to the system (glibc keeps freed memory in its per-thread arenas;
/// without this, reads on different threads one after the other would grow the process as if they had
/// run at once). Call it on the blocking thread of a read, after its mesh is dropped.
pub fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `malloc_trim` only returns free heap pages to the kernel; it is thread-safe.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// The budget's unit: permits are KiB (a tokio semaphore takes at most `u32::MAX` permits at once).
const UNIT: u64 = 1024;

/// Why a share of the budget was not granted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BudgetRefusal {
    /// The charge alone exceeds its whole pool (`budget` bytes).
    TooLarge { charge: u64, budget: u64 },
    /// The pool stayed taken for the whole wait.
    Busy { waited_s: u64 },
}

/// The two steps of a read, each charged to its own part of the budget (see [`AssetBudget`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReadStep {
    /// The file's bytes.
    File,
    /// The parsed mesh and its checks.
    Parse,
}

/// One part of the budget: a semaphore of KiB.
#[derive(Debug, Clone)]
struct Pool {
    slots: Arc<Semaphore>,
    units: u64,
}

impl Pool {
    fn new(bytes: u64) -> Pool {
        let units = (bytes / UNIT).clamp(1, u64::from(u32::MAX));
        Pool {
            slots: Arc::new(Semaphore::new(units as usize)),
            units,
        }
    }
}

/// The server-wide byte budget of mesh reads, in two parts: a quarter for the files
/// ([`ReadStep::File`]) and the rest for their parses ([`ReadStep::Parse`]). A read takes its file's share,
/// then — holding it — its parse's; keeping the parts apart is what keeps that from deadlocking: the reads
/// that hold parse shares wait for nothing more, so they finish and free the parse part for the reads that
/// wait with their files (with one pool, reads holding file shares could take all of it and each wait for
/// the others).
#[derive(Debug, Clone)]
pub struct AssetBudget {
    files: Pool,
    parses: Pool,
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
    /// A budget of `bytes` (a quarter for files, the rest for parses) whose requests wait at most `wait`.
    pub fn new(bytes: u64, wait: Duration) -> AssetBudget {
        let files = AssetBudget::file_part(bytes);
        AssetBudget {
            files: Pool::new(files),
            parses: Pool::new(bytes - files),
            wait,
            in_use: Arc::new(AtomicU64::new(0)),
            peak: Arc::new(AtomicU64::new(0)),
        }
    }

    /// The part of a budget of `bytes` that holds files: a quarter.
    pub fn file_part(bytes: u64) -> u64 {
        bytes / 4
    }

    /// The first charge of a read: a file of `bytes` bytes (its copies, [`FILE_COPIES`]).
    pub fn file_charge(bytes: u64) -> u64 {
        bytes.saturating_mul(FILE_COPIES)
    }

    /// The second charge of a read: the parsed mesh and its checks, for a file of `elements`
    /// ([`mesh_elements`]).
    pub fn parse_charge(elements: u64) -> u64 {
        elements.saturating_mul(BYTES_PER_ELEMENT)
    }

    /// The whole budget, bytes.
    pub fn bytes(&self) -> u64 {
        (self.files.units + self.parses.units) * UNIT
    }

    /// Bytes held by granted shares now.
    pub fn in_use(&self) -> u64 {
        self.in_use.load(Ordering::SeqCst)
    }

    /// The most bytes held at once since the server started.
    pub fn peak(&self) -> u64 {
        self.peak.load(Ordering::SeqCst)
    }

    /// Waits (at most the configured wait) for a share of `charge` bytes for `step`.
    pub async fn acquire(&self, step: ReadStep, charge: u64) -> Result<BudgetShare, BudgetRefusal> {
        let pool = match step {
            ReadStep::File => &self.files,
            ReadStep::Parse => &self.parses,
        };
        let units = charge.div_ceil(UNIT).max(1);
        if units > pool.units {
            return Err(BudgetRefusal::TooLarge {
                charge,
                budget: pool.units * UNIT,
            });
        }
        let permit = tokio::time::timeout(
            self.wait,
            pool.slots.clone().acquire_many_owned(units as u32),
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
    async fn shares_wait_for_each_other_and_are_refused_beyond_their_part() {
        // 40 KiB: 10 for files, 30 for parses.
        let budget = AssetBudget::new(40 * 1024, Duration::from_millis(50));
        let a = budget.acquire(ReadStep::File, 6 * 1024).await.unwrap();
        assert_eq!(budget.in_use(), 6 * 1024);
        // 6 + 6 KiB > 10 KiB of files: the second waits, then is refused as busy.
        assert_eq!(
            budget.acquire(ReadStep::File, 6 * 1024).await.unwrap_err(),
            BudgetRefusal::Busy { waited_s: 0 }
        );
        // The parses have their own part.
        let p = budget.acquire(ReadStep::Parse, 20 * 1024).await.unwrap();
        assert_eq!(budget.in_use(), 26 * 1024);
        drop((a, p));
        assert_eq!(budget.in_use(), 0);
        let _b = budget.acquire(ReadStep::File, 6 * 1024).await.unwrap();
        assert_eq!(budget.peak(), 26 * 1024);
        assert_eq!(
            budget.acquire(ReadStep::File, 11 * 1024).await.unwrap_err(),
            BudgetRefusal::TooLarge {
                charge: 11 * 1024,
                budget: 10 * 1024
            }
        );
        assert!(matches!(
            budget.acquire(ReadStep::Parse, 31 * 1024).await,
            Err(BudgetRefusal::TooLarge { .. })
        ));
    }

    #[test]
    fn elements_are_bounded_without_parsing() {
        use skintight_geometry::mesh::io::{MeshFormat, WriteParams, write_mesh_bytes};
        let mesh = skintight_geometry::test_meshes::icosphere(2, 1.0);
        let real = (mesh.num_vertices() + mesh.num_faces()) as u64;
        for (format, ext) in [
            (MeshFormat::Obj, "obj"),
            (MeshFormat::Stl, "stl"),
            (MeshFormat::Ply, "ply"),
            (MeshFormat::Glb, "glb"),
        ] {
            let bytes = write_mesh_bytes(&mesh, format, &WriteParams::default()).unwrap();
            let n = mesh_elements(&bytes, ext);
            // An upper bound, and a close one (not the bound by length) where the counts can be read.
            assert!(n >= real, "{ext}: {n} < {real}");
            assert!(n <= 3 * real, "{ext}: {n} for {real} elements");
        }
        // Short lines: one element each.
        assert_eq!(
            mesh_elements(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "obj"),
            5
        );
        // Counts that cannot be read: bounded by the length.
        assert_eq!(mesh_elements(&[0u8; 30], "glb"), 11);
    }
}
