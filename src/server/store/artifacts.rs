//! Stored artifacts of completed jobs (written by [`finish`](EngineStore::finish)), listed, described and
//! read in chunks of at most [`CHUNK_BYTES`](super::CHUNK_BYTES) for downloads, never whole.

use super::engine::{Engine, EngineStore};
use super::statement::Statement;
use crate::server::model::ArtifactInfo;
use crate::server::store::ArtifactMeta;

/// The artifact statements in which the dialects differ.
pub trait ArtifactsSql {
    /// Stores an artifact, replacing one of the same job and name (job id, name, content type, bytes,
    /// sha256, data).
    const SAVE_ARTIFACT: &'static str;
    /// Up to `$4` bytes of an artifact (job id, name) from the 0-based byte `$3`, as the column `chunk`
    /// (empty past its end).
    const ARTIFACT_CHUNK: &'static str;
}

/// A job's artifacts by name (job id).
const LIST: &str =
    "SELECT name, content_type, bytes, sha256 FROM artifacts WHERE job_id = $1 ORDER BY name";
/// One artifact's description (job id, name).
const META: &str =
    "SELECT content_type, sha256, bytes FROM artifacts WHERE job_id = $1 AND name = $2";

impl<E: Engine + ArtifactsSql> EngineStore<E> {
    /// [`Store::list_artifacts`](super::Store::list_artifacts) on this engine.
    pub async fn list_artifacts(&self, job_id: &str) -> Result<Vec<ArtifactInfo>, sqlx::Error> {
        let rows = Statement::<E>::new(LIST)
            .bind(job_id)
            .fetch_all(&mut *self.conn().await?)
            .await?;
        rows.iter()
            .map(|r| {
                Ok(ArtifactInfo {
                    name: E::get(r, "name")?,
                    content_type: E::get(r, "content_type")?,
                    bytes: E::get(r, "bytes")?,
                    sha256: E::get(r, "sha256")?,
                })
            })
            .collect()
    }

    /// [`Store::artifact_meta`](super::Store::artifact_meta) on this engine.
    pub async fn artifact_meta(
        &self,
        job_id: &str,
        name: &str,
    ) -> Result<Option<ArtifactMeta>, sqlx::Error> {
        let row = Statement::<E>::new(META)
            .bind(job_id)
            .bind(name)
            .fetch_optional(&mut *self.conn().await?)
            .await?;
        row.map(|row| {
            Ok(ArtifactMeta {
                content_type: E::get(&row, "content_type")?,
                sha256: E::get(&row, "sha256")?,
                bytes: E::get(&row, "bytes")?,
            })
        })
        .transpose()
    }

    /// [`Store::artifact_chunk`](super::Store::artifact_chunk) on this engine.
    pub async fn artifact_chunk(
        &self,
        job_id: &str,
        name: &str,
        offset: i64,
        len: i64,
    ) -> Result<Vec<u8>, sqlx::Error> {
        let row = Statement::<E>::new(E::ARTIFACT_CHUNK)
            .bind(job_id)
            .bind(name)
            .bind(offset)
            .bind(len)
            .fetch_optional(&mut *self.conn().await?)
            .await?;
        let data = match row {
            Some(row) => E::get::<Option<Vec<u8>>>(&row, "chunk")?,
            None => None,
        };
        Ok(data.unwrap_or_default())
    }
}
