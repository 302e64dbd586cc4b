//! Stored artifacts of completed jobs (written by [`Store::finish`](super::Store::finish)).

use sqlx::Row;

use super::Store;
use crate::server::model::ArtifactInfo;

impl Store {
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

    /// One artifact's content type, SHA-256 and bytes.
    pub async fn artifact(
        &self,
        job_id: &str,
        name: &str,
    ) -> Result<Option<(String, String, Vec<u8>)>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT content_type, sha256, data FROM artifacts WHERE job_id = ?1 AND name = ?2",
        )
        .bind(job_id)
        .bind(name)
        .fetch_optional(&self.pool)
        .await?;
        row.map(|row| {
            Ok((
                row.try_get("content_type")?,
                row.try_get("sha256")?,
                row.try_get("data")?,
            ))
        })
        .transpose()
    }
}
