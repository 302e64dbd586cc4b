//! SQLite's artifact statements: `INSERT OR REPLACE`, and `substr` of a `BLOB`, which counts bytes from 1.

use sqlx::Sqlite;

use crate::server::store::artifacts::ArtifactsSql;

impl ArtifactsSql for Sqlite {
    const SAVE_ARTIFACT: &'static str = "INSERT OR REPLACE INTO artifacts \
         (job_id, name, content_type, bytes, sha256, data) VALUES ($1, $2, $3, $4, $5, $6)";
    const ARTIFACT_CHUNK: &'static str =
        "SELECT substr(data, $3 + 1, $4) AS chunk FROM artifacts WHERE job_id = $1 AND name = $2";
}
