//! `POST /v1/assets`: raw mesh bytes, content-addressed by SHA-256 and deduplicated per tenant;
//! `GET /v1/assets/{id}`: its metadata.
//!
//! The format comes from `?format=`, else the extension of `?filename=`, else the Content-Type
//! (`model/obj`, `model/stl`, `application/sla`, `model/ply`, `application/ply`, `model/gltf-binary`):
//! exactly the surface formats the mesh readers (`skintight_geometry::mesh::io`) read.

use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, RawQuery, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::IntoResponse;
use serde::Deserialize;
use serde_json::json;
use sha2::{Digest, Sha256};
use sqlx::Row;

use skintight_geometry::mesh::io::MeshFormat;

use super::AppState;
use super::auth::Tenant;
use super::error::ApiError;
use super::runner::Asset;

/// Mesh formats accepted: those `skintight_geometry::mesh::io::read_mesh_bytes` reads.
pub const FORMATS: &[&str] = &["obj", "stl", "ply", "glb"];

/// Lower-case hex SHA-256.
pub fn sha256_hex(data: &[u8]) -> String {
    hex::encode(Sha256::digest(data))
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct UploadQuery {
    filename: Option<String>,
    format: Option<String>,
}

/// Parses a query string into `T`, naming the parameter at fault.
pub fn parse_query<T: serde::de::DeserializeOwned + Default>(
    raw: Option<&str>,
) -> Result<T, ApiError> {
    let Some(raw) = raw.filter(|r| !r.is_empty()) else {
        return Ok(T::default());
    };
    let de = serde_urlencoded::Deserializer::new(form_urlencoded_parse(raw));
    serde_path_to_error::deserialize::<_, T>(de).map_err(|e| {
        let path = e.path().to_string();
        let msg = e.into_inner().to_string();
        let field = super::error::field_of(&path, &msg);
        ApiError::invalid(field, format!("query parameter: {msg}"))
    })
}

fn form_urlencoded_parse(raw: &str) -> form_urlencoded::Parse<'_> {
    form_urlencoded::parse(raw.as_bytes())
}

fn format_of(q: &UploadQuery, headers: &HeaderMap) -> Result<String, ApiError> {
    if let Some(f) = &q.format {
        let f = f.to_ascii_lowercase();
        return if FORMATS.contains(&f.as_str()) {
            Ok(f)
        } else {
            Err(ApiError::invalid(
                "format",
                format!(
                    "unsupported mesh format {f:?}; supported: {}",
                    FORMATS.join(", ")
                ),
            ))
        };
    }
    if let Some(name) = &q.filename {
        let ext = name.rsplit_once('.').map(|(_, e)| e.to_ascii_lowercase());
        return match ext {
            Some(e) if FORMATS.contains(&e.as_str()) => Ok(e),
            _ => Err(ApiError::invalid(
                "filename",
                format!(
                    "cannot tell the mesh format from the file name {name:?}; use one ending in .{}",
                    FORMATS.join(", .")
                ),
            )),
        };
    }
    let ct = headers
        .get(axum::http::header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok());
    match ct {
        Some(ct) => MeshFormat::from_content_type(ct)
            .map(|f| f.extension().to_string())
            .ok_or_else(|| {
                ApiError::invalid(
                    "Content-Type",
                    format!(
                        "cannot tell the mesh format from Content-Type {ct:?}; send model/obj, model/stl, \
                         model/ply or model/gltf-binary, or add ?filename=body.obj"
                    ),
                )
            }),
        None => Err(ApiError::invalid(
            "Content-Type",
            "no Content-Type; send model/obj, model/stl, model/ply or model/gltf-binary, or add \
             ?filename=body.obj",
        )),
    }
}

/// Maps a body-reading failure (too large, broken connection) into the envelope.
pub fn body_error(rejection: BytesRejection, limit: usize) -> ApiError {
    if rejection.status() == StatusCode::PAYLOAD_TOO_LARGE {
        ApiError::too_large(
            "body",
            format!("the request body is larger than the limit of {limit} bytes"),
        )
    } else {
        ApiError::bad_request(
            "bad_body",
            format!("cannot read the request body: {rejection}"),
        )
    }
}

/// `POST /v1/assets`.
pub async fn upload(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<impl IntoResponse, ApiError> {
    let q: UploadQuery = parse_query(query.as_deref())?;
    let format = format_of(&q, &headers)?;
    let body = body.map_err(|r| body_error(r, state.config.server.max_asset_bytes))?;
    if body.is_empty() {
        return Err(ApiError::invalid("body", "the uploaded mesh is empty"));
    }
    let sha = sha256_hex(&body);
    let id = uuid::Uuid::now_v7().to_string();
    let inserted = sqlx::query(
        "INSERT INTO assets (id, tenant, sha256, bytes, format, data) VALUES (?1, ?2, ?3, ?4, ?5, ?6) \
         ON CONFLICT (tenant, sha256) DO NOTHING",
    )
    .bind(&id)
    .bind(&tenant)
    .bind(&sha)
    .bind(body.len() as i64)
    .bind(&format)
    .bind(body.as_ref())
    .execute(&state.pool)
    .await?
    .rows_affected()
        == 1;
    let row = sqlx::query("SELECT id, sha256, bytes, format, created_at FROM assets WHERE tenant = ?1 AND sha256 = ?2")
        .bind(&tenant)
        .bind(&sha)
        .fetch_one(&state.pool)
        .await?;
    let status = if inserted {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    Ok((status, axum::Json(asset_json(&row)?)))
}

fn asset_json(row: &sqlx::sqlite::SqliteRow) -> Result<serde_json::Value, ApiError> {
    Ok(json!({
        "id": row.try_get::<String, _>("id")?,
        "sha256": row.try_get::<String, _>("sha256")?,
        "bytes": row.try_get::<i64, _>("bytes")?,
        "format": row.try_get::<String, _>("format")?,
        "created_at": row.try_get::<String, _>("created_at")?,
    }))
}

/// `GET /v1/assets/{id}`.
pub async fn show(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(id): Path<String>,
) -> Result<impl IntoResponse, ApiError> {
    let row = sqlx::query(
        "SELECT id, sha256, bytes, format, created_at FROM assets WHERE id = ?1 AND tenant = ?2",
    )
    .bind(&id)
    .bind(&tenant)
    .fetch_optional(&state.pool)
    .await?
    .ok_or_else(|| ApiError::not_found("asset", &id))?;
    Ok(axum::Json(asset_json(&row)?))
}

/// Loads one asset of a tenant, bytes included.
pub async fn load(
    pool: &sqlx::SqlitePool,
    tenant: &str,
    id: &str,
) -> Result<Option<Asset>, sqlx::Error> {
    let row =
        sqlx::query("SELECT id, format, sha256, data FROM assets WHERE id = ?1 AND tenant = ?2")
            .bind(id)
            .bind(tenant)
            .fetch_optional(pool)
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
