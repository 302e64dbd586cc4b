//! Uploaded assets: content-addressed by SHA-256 and deduplicated per tenant (a unique `(tenant, sha256)`).
//! Both dialects run the same statements.

use super::engine::{Engine, EngineStore};
use super::rows;
use super::statement::Statement;
use crate::server::model::{Asset, AssetInfo, sha256_hex};

/// Inserts an asset unless the tenant has its bytes (id, tenant, sha256, bytes, format, data).
const INSERT: &str = "INSERT INTO assets (id, tenant, sha256, bytes, format, data) \
     VALUES ($1, $2, $3, $4, $5, $6) ON CONFLICT (tenant, sha256) DO NOTHING";
/// A tenant's asset by its bytes' SHA-256 (tenant, sha256).
const BY_SHA: &str =
    "SELECT id, sha256, bytes, format, created_at FROM assets WHERE tenant = $1 AND sha256 = $2";
/// A tenant's asset's metadata (id, tenant).
const INFO: &str =
    "SELECT id, sha256, bytes, format, created_at FROM assets WHERE id = $1 AND tenant = $2";
/// A tenant's asset with its bytes (id, tenant).
const LOAD: &str = "SELECT id, format, sha256, data FROM assets WHERE id = $1 AND tenant = $2";

impl<E: Engine> EngineStore<E> {
    /// [`Store::insert_asset`](super::Store::insert_asset) on this engine.
    pub async fn insert_asset(
        &self,
        id: &str,
        tenant: &str,
        format: &str,
        data: &[u8],
    ) -> Result<(AssetInfo, bool), sqlx::Error> {
        let sha = sha256_hex(data);
        let inserted = Statement::<E>::new(INSERT)
            .bind(id)
            .bind(tenant)
            .bind(sha.as_str())
            .bind(data.len() as i64)
            .bind(format)
            .bind(data)
            .execute(&mut *self.conn().await?)
            .await?
            == 1;
        let row = Statement::<E>::new(BY_SHA)
            .bind(tenant)
            .bind(sha.as_str())
            .fetch_one(&mut *self.conn().await?)
            .await?;
        Ok((rows::asset_info::<E>(&row)?, inserted))
    }

    /// [`Store::asset_info`](super::Store::asset_info) on this engine.
    pub async fn asset_info(
        &self,
        tenant: &str,
        id: &str,
    ) -> Result<Option<AssetInfo>, sqlx::Error> {
        let row = Statement::<E>::new(INFO)
            .bind(id)
            .bind(tenant)
            .fetch_optional(&mut *self.conn().await?)
            .await?;
        row.as_ref().map(rows::asset_info::<E>).transpose()
    }

    /// [`Store::load_asset`](super::Store::load_asset) on this engine.
    pub async fn load_asset(&self, tenant: &str, id: &str) -> Result<Option<Asset>, sqlx::Error> {
        let row = Statement::<E>::new(LOAD)
            .bind(id)
            .bind(tenant)
            .fetch_optional(&mut *self.conn().await?)
            .await?;
        row.map(|row| {
            Ok(Asset {
                id: E::get(&row, "id")?,
                format: E::get(&row, "format")?,
                sha256: E::get(&row, "sha256")?,
                data: E::get(&row, "data")?,
            })
        })
        .transpose()
    }
}
