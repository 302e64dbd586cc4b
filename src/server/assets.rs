//! `POST /v1/assets`: raw mesh bytes, content-addressed by SHA-256 and deduplicated per tenant;
//! `GET /v1/assets/{id}`: its metadata.
//!
//! The format comes from `?format=`, else the extension of `?filename=`, else the Content-Type
//! (`model/obj`, `model/stl`, `application/sla`, `model/ply`, `application/ply`, `model/gltf-binary`):
//! exactly the surface formats the mesh readers (`skintight_geometry::mesh::io`) read. The bytes are read
//! as that format on arrival: an upload that does not parse, has no triangle or a coordinate that is not a
//! finite number, is refused with 422 (field `body`) and not stored. Reading it takes shares of the
//! server's budget for meshes ([`super::asset_budget`]): the declared `Content-Length` before a byte of the
//! body is read, then the parse by the file's elements, counted before it is parsed.

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::extract::{Path, RawQuery, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::IntoResponse;
use serde::Deserialize;

use skintight_geometry::mesh::io::{MeshFormat, read_mesh_bytes};

use super::asset_budget::{AssetBudget, ReadStep, mesh_elements, release_freed_memory};
use super::error::ApiError;
use super::keys::Tenant;
use super::request::{body_error, budget_error, parse_query};
use super::state::AppState;

/// Mesh formats accepted: those `skintight_geometry::mesh::io::read_mesh_bytes` reads.
pub const FORMATS: &[&str] = &["obj", "stl", "ply", "glb"];

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct UploadQuery {
    filename: Option<String>,
    format: Option<String>,
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

/// Reads uploaded bytes as a mesh of `format`: it must parse and have at least one triangle. (Whether it
/// can serve a purpose — a closed body surface, a pose with the body's vertices — is checked when a job
/// names it.)
fn check_mesh(bytes: &[u8], format: &str) -> Result<(), ApiError> {
    let f = MeshFormat::from_extension(format).ok_or_else(|| {
        ApiError::invalid("format", format!("unsupported mesh format {format:?}"))
    })?;
    let mesh = read_mesh_bytes(bytes, f).map_err(|e| {
        ApiError::invalid(
            "body",
            format!("the upload cannot be read as {format}: {e}; send a mesh file in that format"),
        )
    })?;
    if mesh.num_faces() == 0 {
        return Err(ApiError::invalid(
            "body",
            format!("the upload read as {format} has no faces; a mesh asset needs triangles"),
        ));
    }
    if let Some(i) = mesh
        .positions
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
    {
        return Err(ApiError::invalid(
            "body",
            format!(
                "vertex {i} of the upload has a coordinate that is not a finite number (NaN or infinite); \
                 a mesh asset needs finite coordinates"
            ),
        ));
    }
    Ok(())
}

/// The request's `Content-Length`, if it declares one.
pub fn declared_length(headers: &HeaderMap) -> Option<u64> {
    headers
        .get(axum::http::header::CONTENT_LENGTH)?
        .to_str()
        .ok()?
        .trim()
        .parse()
        .ok()
}

fn too_large(limit: usize) -> ApiError {
    ApiError::too_large(
        "body",
        format!("the request body is larger than the limit of {limit} bytes"),
    )
}

/// `POST /v1/assets`.
pub async fn upload(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
    req: Request,
) -> Result<impl IntoResponse, ApiError> {
    let q: UploadQuery = parse_query(query.as_deref())?;
    let format = format_of(&q, &headers)?;
    let limit = state.config.server.max_asset_bytes;
    // The share of the server's budget for meshes comes before the first byte is read: the body and
    // its parse are charged by the declared length (the limit when none is declared).
    let declared = declared_length(&headers);
    if let Some(n) = declared
        && n > limit as u64
    {
        return Err(too_large(limit));
    }
    let file_share = state
        .asset_budget
        .acquire(
            ReadStep::File,
            AssetBudget::file_charge(declared.unwrap_or(limit as u64)),
        )
        .await
        .map_err(|e| budget_error(e, "body"))?;
    // Read under the route's `DefaultBodyLimit` of `server.max_asset_bytes`.
    let body = Bytes::from_request(req, &())
        .await
        .map_err(|r| body_error(r, limit))?;
    if body.is_empty() {
        return Err(ApiError::invalid("body", "the uploaded mesh is empty"));
    }
    // Then the parse's share, from the file's elements counted without parsing it.
    let count = body.clone();
    let fmt = format.clone();
    let elements = tokio::task::spawn_blocking(move || mesh_elements(&count, &fmt))
        .await
        .map_err(ApiError::internal)?;
    let parse_share = state
        .asset_budget
        .acquire(ReadStep::Parse, AssetBudget::parse_charge(elements))
        .await
        .map_err(|e| budget_error(e, "body"))?;
    // Parsed on arrival (off the async runtime's threads), so that bytes no job can read are refused now,
    // naming the problem, rather than stored and failed at submission or run time. The shares are held
    // until the bytes are stored (the body lives until then).
    let check = body.clone();
    let fmt = format.clone();
    let checked = tokio::task::spawn_blocking(move || {
        let checked = check_mesh(&check, &fmt);
        release_freed_memory();
        drop(parse_share);
        checked
    })
    .await
    .map_err(ApiError::internal)?;
    checked?;
    let id = uuid::Uuid::now_v7().to_string();
    let (asset, inserted) = state
        .store
        .insert_asset(&id, &tenant, &format, body.as_ref())
        .await?;
    drop(file_share);
    let status = if inserted {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    Ok((status, axum::Json(asset.to_json())))
}

/// `GET /v1/assets/{id}`.
pub async fn show(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(id): Path<String>,
) -> Result<impl IntoResponse, ApiError> {
    let asset = state
        .store
        .asset_info(&tenant, &id)
        .await?
        .ok_or_else(|| ApiError::not_found("asset", &id))?;
    Ok(axum::Json(asset.to_json()))
}
