//! Stored artifacts of completed jobs (written by [`Store::finish`](super::Store::finish)).

use sqlx::Row;

use super::SqliteStore;
use crate::server::model::ArtifactInfo;
use crate::server::store::ArtifactMeta;

impl SqliteStore {
    /// The artifacts of a job, by name.
    pub async fn list_artifacts(&self, job_id: &str) -> Result<Vec<ArtifactInfo>, sqlx::Error> {
        let rows = sqlx::query(
            "SELECT name, content_type, bytes, sha256 FROM artifacts WHERE job_id = ?1 ORDER BY name",
        )
        .bind(job_id)
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|r| {
                Ok(ArtifactInfo {
                    name: r.try_get("name")?,
                    content_type: r.try_get("content_type")?,
                    bytes: r.try_get("bytes")?,
                    sha256: r.try_get("sha256")?,
                })
            })
            .collect()
    }

    /// One artifact's content type, SHA-256 and size.
    pub async fn artifact_meta(
        &self,
        job_id: &str,
        name: &str,
    ) -> Result<Option<ArtifactMeta>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT content_type, sha256, bytes FROM artifacts WHERE job_id = ?1 AND name = ?2",
        )
        .bind(job_id)
        .bind(name)
        .fetch_optional(&self.pool)
        .await?;
        row.map(|row| {
            Ok(ArtifactMeta {
                content_type: row.try_get("content_type")?,
                sha256: row.try_get("sha256")?,
                bytes: row.try_get("bytes")?,
            })
        })
        .transpose()
    }

    /// Up to `len` bytes of an artifact from byte `offset` (`substr` of a BLOB counts bytes, from 1).
    pub async fn artifact_chunk(
        &self,
        job_id: &str,
        name: &str,
        offset: i64,
        len: i64,
    ) -> Result<Vec<u8>, sqlx::Error> {
        let data: Option<Vec<u8>> = sqlx::query_scalar(
            "SELECT substr(data, ?3 + 1, ?4) FROM artifacts WHERE job_id = ?1 AND name = ?2",
        )
        .bind(job_id)
        .bind(name)
        .bind(offset)
        .bind(len)
        .fetch_optional(&self.pool)
        .await?
        .flatten();
        Ok(data.unwrap_or_default())
    }
}
