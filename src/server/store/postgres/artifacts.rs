//! PostgreSQL's artifact statements: an upsert on `(job_id, name)`, and `substring` of a `bytea`, which
//! counts bytes from 1 (PostgreSQL reads only the slices of the TOASTed value it needs when the column is
//! stored uncompressed, and decompresses it otherwise).

use sqlx::Postgres;

use crate::server::store::artifacts::ArtifactsSql;

impl ArtifactsSql for Postgres {
    const SAVE_ARTIFACT: &'static str = "INSERT INTO artifacts \
         (job_id, name, content_type, bytes, sha256, data) VALUES ($1, $2, $3, $4, $5, $6) \
         ON CONFLICT (job_id, name) DO UPDATE SET content_type = EXCLUDED.content_type, \
             bytes = EXCLUDED.bytes, sha256 = EXCLUDED.sha256, data = EXCLUDED.data";
    const ARTIFACT_CHUNK: &'static str = "SELECT substring(data FROM ($3 + 1)::int FOR $4::int) AS chunk \
         FROM artifacts WHERE job_id = $1 AND name = $2";
}
