//! Uploaded assets: content-addressed by SHA-256 and deduplicated per tenant.

use sqlx::Row;

use super::{SqliteStore, asset_info};
use crate::server::model::{Asset, AssetInfo, sha256_hex};

impl SqliteStore {
    /// Stores `data` for `tenant` under the new id `id` unless the tenant already has the same bytes;
    /// returns the asset (new or existing) and whether it was inserted.
    pub async fn insert_asset(
        &self,
        id: &str,
        tenant: &str,
        format: &str,
        data: &[u8],
    ) -> Result<(AssetInfo, bool), sqlx::Error> {
        let sha = sha256_hex(data);
        let inserted = sqlx::query(
            "INSERT INTO assets (id, tenant, sha256, bytes, format, data) VALUES (?1, ?2, ?3, ?4, ?5, ?6) \
             ON CONFLICT (tenant, sha256) DO NOTHING",
        )
        .bind(id)
        .bind(tenant)
        .bind(&sha)
        .bind(data.len() as i64)
        .bind(format)
        .bind(data)
        .execute(&self.pool)
        .await?
        .rows_affected()
            == 1;
        let row = sqlx::query(
            "SELECT id, sha256, bytes, format, created_at FROM assets WHERE tenant = ?1 AND sha256 = ?2",
        )
        .bind(tenant)
        .bind(&sha)
        .fetch_one(&self.pool)
        .await?;
        Ok((asset_info(&row)?, inserted))
    }

    /// The metadata of one asset of a tenant.
    pub async fn asset_info(
        &self,
        tenant: &str,
        id: &str,
    ) -> Result<Option<AssetInfo>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT id, sha256, bytes, format, created_at FROM assets WHERE id = ?1 AND tenant = ?2",
        )
        .bind(id)
        .bind(tenant)
        .fetch_optional(&self.pool)
        .await?;
        row.as_ref().map(asset_info).transpose()
    }

    /// Loads one asset of a tenant, bytes included.
    pub async fn load_asset(&self, tenant: &str, id: &str) -> Result<Option<Asset>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT id, format, sha256, data FROM assets WHERE id = ?1 AND tenant = ?2",
        )
        .bind(id)
        .bind(tenant)
        .fetch_optional(&self.pool)
        .await?;
        row.map(|row| {
            Ok(Asset {
                id: row.try_get("id")?,
                format: row.try_get("format")?,
                sha256: row.try_get("sha256")?,
                data: row.try_get("data")?,
            })
        })
        .transpose()
    }
}
