//! Job routes: submit (with `Idempotency-Key`), list (newest first, cursor pagination), show, cancel, and
//! artifacts.
//!
//! Submission parses and validates the spec once, through its kind ([`JobRegistry::accept`]), checks the
//! assets it names, and stores the canonical JSON as a `queued` job (see [`super::runner`] for the whole
//! path of a spec).
//!
//! [`JobRegistry::accept`]: super::runner::JobRegistry::accept

use std::collections::BTreeMap;

use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, RawQuery, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use serde_json::{Value, json};

use super::asset_budget::{
    AssetBudget, BudgetShare, ReadStep, mesh_elements, release_freed_memory,
};
use super::error::{ApiError, parse_json};
use super::keys::Tenant;
use super::model::{
    AssetRef, Assets, CancelResult, Inserted, JobRow, NewJob, STATUSES, sha256_hex,
};
use super::queue;
use super::request::{accept_instead, body_error, budget_error, parse_query};
use super::runner::ParsedSpec;
use super::state::AppState;
use super::store::CHUNK_BYTES;

/// Body of `POST /v1/jobs`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SubmitJob {
    kind: String,
    spec: Value,
}

/// The request path of a field inside the spec: `spec.a.b`, `spec[0]` style indices kept attached
/// (`spec.panels[2]`), and `spec` itself for the spec as a whole (an empty field).
pub fn spec_field(field: &str) -> String {
    if field.is_empty() {
        "spec".to_string()
    } else if field.starts_with('[') {
        format!("spec{field}")
    } else {
        format!("spec.{field}")
    }
}

/// Sorts object keys recursively so that equal JSON documents hash equally.
fn canonical(v: &Value) -> Value {
    match v {
        Value::Object(m) => {
            let sorted: BTreeMap<_, _> = m.iter().map(|(k, v)| (k.clone(), canonical(v))).collect();
            Value::Object(sorted.into_iter().collect())
        }
        Value::Array(a) => Value::Array(a.iter().map(canonical).collect()),
        other => other.clone(),
    }
}

fn idempotency_key(headers: &HeaderMap) -> Result<Option<String>, ApiError> {
    let Some(v) = headers.get("idempotency-key") else {
        return Ok(None);
    };
    let s = v
        .to_str()
        .ok()
        .map(str::trim)
        .filter(|s| !s.is_empty() && s.len() <= 255)
        .ok_or_else(|| {
            ApiError::invalid(
                "Idempotency-Key",
                "must be 1 to 255 visible ASCII characters",
            )
        })?;
    Ok(Some(s.to_string()))
}

/// A JSON route's `Content-Type` must be `application/json`, with no `charset` or `charset=utf-8` (JSON is
/// UTF-8, RFC 8259 §8.1); anything else, or none, is answered 415.
pub fn require_json(headers: &HeaderMap) -> Result<(), ApiError> {
    let ct = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    let mut parts = ct.split(';');
    let essence = parts.next().unwrap_or("").trim();
    let charset = parts
        .filter_map(|p| p.split_once('='))
        .find(|(k, _)| k.trim().eq_ignore_ascii_case("charset"))
        .map(|(_, v)| v.trim().trim_matches('"'));
    let utf8 =
        charset.is_none_or(|c| c.eq_ignore_ascii_case("utf-8") || c.eq_ignore_ascii_case("utf8"));
    if essence.eq_ignore_ascii_case("application/json") && utf8 {
        return Ok(());
    }
    let got = if ct.is_empty() {
        "no Content-Type".to_string()
    } else {
        format!("Content-Type {ct:?}")
    };
    Err(ApiError::new(
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
        "unsupported_media_type",
        format!(
            "the body must be JSON in UTF-8 sent as Content-Type: application/json (charset=utf-8 or \
             none); got {got}"
        ),
    )
    .with_field("Content-Type"))
}

/// `POST /v1/jobs`.
pub async fn submit(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    require_json(&headers)?;
    let body = body.map_err(|r| body_error(r, state.config.server.max_json_bytes))?;
    let key = idempotency_key(&headers)?;
    let req: SubmitJob = parse_json(&body)?;
    if !req.spec.is_object() {
        return Err(ApiError::invalid(
            "spec",
            "the spec must be a JSON object (the job kind's document, e.g. a scene for \"simulate\")",
        ));
    }
    let spec_text = req.spec.to_string();
    if spec_text.len() > state.config.jobs.max_spec_bytes {
        return Err(ApiError::too_large(
            "spec",
            format!(
                "the spec has {} bytes of JSON, more than the limit of {}",
                spec_text.len(),
                state.config.jobs.max_spec_bytes
            ),
        ));
    }
    // The one parse and validation of the spec before it is stored.
    let spec = state
        .registry
        .accept(&req.kind, &req.spec)
        .ok_or_else(|| {
            ApiError::invalid(
                "kind",
                format!(
                    "unknown job kind {:?}; this server runs: {}",
                    req.kind,
                    state.registry.kinds().join(", ")
                ),
            )
        })?
        .map_err(|e| ApiError::invalid(spec_field(&e.field), e.message))?;
    // The assets' sizes first: reading them takes shares of the server's budget for meshes
    // (`server.asset_check_memory_bytes`) — the files before they are loaded, their parse before they are
    // checked — held until the checks below are done.
    let refs = spec.assets();
    let mut file_bytes = 0u64;
    let mut largest: Option<(u64, &str)> = None;
    for r in &refs {
        let Some(info) = state.store.asset_info(&tenant, &r.id).await? else {
            return Err(unknown_asset(r));
        };
        let n = info.bytes.max(0) as u64;
        file_bytes = file_bytes.saturating_add(n);
        if largest.is_none_or(|(l, _)| n > l) {
            largest = Some((n, r.field.as_str()));
        }
    }
    let Some((_, largest)) = largest else {
        return admit(
            state,
            tenant,
            req,
            spec,
            spec_text,
            key,
            Assets::default(),
            Vec::new(),
        )
        .await;
    };
    let largest = spec_field(largest);
    let file_share = state
        .asset_budget
        .acquire(ReadStep::File, AssetBudget::file_charge(file_bytes))
        .await
        .map_err(|e| budget_error(e, &largest))?;
    let mut assets = Assets::default();
    for r in refs {
        let Some(asset) = state.store.load_asset(&tenant, &r.id).await? else {
            return Err(unknown_asset(&r));
        };
        assets.by_field.insert(r.field, asset);
    }
    let (assets, elements) = tokio::task::spawn_blocking(move || {
        let n = assets
            .by_field
            .values()
            .map(|a| mesh_elements(&a.data, &a.format))
            .fold(0u64, u64::saturating_add);
        (assets, n)
    })
    .await
    .map_err(ApiError::internal)?;
    let parse_share = state
        .asset_budget
        .acquire(ReadStep::Parse, AssetBudget::parse_charge(elements))
        .await
        .map_err(|e| budget_error(e, &largest))?;
    admit(
        state,
        tenant,
        req,
        spec,
        spec_text,
        key,
        assets,
        vec![file_share, parse_share],
    )
    .await
}

/// The rest of [`submit`] once the assets are loaded: the kind checks them and costs the job (holding
/// `shares` of the server's budget for meshes until it is done), then the job is stored.
#[allow(clippy::too_many_arguments)]
async fn admit(
    state: AppState,
    tenant: String,
    req: SubmitJob,
    spec: ParsedSpec,
    spec_text: String,
    key: Option<String>,
    assets: Assets,
    shares: Vec<BudgetShare>,
) -> Result<Response, ApiError> {
    // Checking the assets and costing the job read meshes: off the async runtime's threads.
    let limits = state.config.jobs.limits();
    tokio::task::spawn_blocking(move || {
        let checked = spec
            .check_assets(&assets)
            .and_then(|()| spec.admit(&assets, &limits));
        drop(assets);
        release_freed_memory();
        drop(shares);
        checked
    })
    .await
    .map_err(ApiError::internal)?
    .map_err(|e| ApiError::invalid(spec_field(&e.field), e.message))?;
    let hash = sha256_hex(
        canonical(&json!({ "kind": req.kind, "spec": req.spec }))
            .to_string()
            .as_bytes(),
    );

    if let Some(key) = &key
        && let Some(resp) = replay(&state, &tenant, key, &hash).await?
    {
        return Ok(resp);
    }

    let job = NewJob {
        id: uuid::Uuid::now_v7().to_string(),
        tenant: tenant.clone(),
        kind: req.kind,
        spec: spec_text,
        idempotency_key: key,
        request_hash: hash,
    };
    match queue::submit(&state, &job).await? {
        Inserted::Queued => {}
        // A concurrent request with the same key won the race: answer as a replay.
        Inserted::KeyTaken => {
            let key = job.idempotency_key.as_deref().unwrap_or_default();
            return replay(&state, &tenant, key, &job.request_hash)
                .await?
                .ok_or_else(|| {
                    ApiError::internal("idempotency key conflict without a stored job")
                });
        }
    }
    let id = job.id;
    let job = state
        .store
        .get_job(&tenant, &id)
        .await?
        .ok_or_else(|| ApiError::internal("a job vanished right after it was stored"))?;
    tracing::info!(job = %id, kind = %job.kind, %tenant, "job queued");
    Ok((
        StatusCode::CREATED,
        [(header::LOCATION, format!("/v1/jobs/{id}"))],
        axum::Json(job.to_json()),
    )
        .into_response())
}

/// 422 for a spec naming an asset the tenant does not have.
fn unknown_asset(r: &AssetRef) -> ApiError {
    ApiError::new(
        StatusCode::UNPROCESSABLE_ENTITY,
        "unknown_asset",
        format!(
            "no asset with id {:?}; upload it with POST /v1/assets first",
            r.id
        ),
    )
    .with_field(spec_field(&r.field))
}

/// An earlier submission with the same idempotency key: the same job (200) when the request was the same,
/// 409 when it differed.
async fn replay(
    state: &AppState,
    tenant: &str,
    key: &str,
    hash: &str,
) -> Result<Option<Response>, ApiError> {
    let Some((stored, job)) = state.store.job_by_idempotency_key(tenant, key).await? else {
        return Ok(None);
    };
    if stored != hash {
        return Err(ApiError::new(
            StatusCode::CONFLICT,
            "idempotency_key_reused",
            "this Idempotency-Key was already used with a different request body",
        )
        .with_field("Idempotency-Key"));
    }
    Ok(Some(
        (StatusCode::OK, axum::Json(job.to_json())).into_response(),
    ))
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct ListQuery {
    status: Option<String>,
    cursor: Option<String>,
    limit: Option<u32>,
}

/// `GET /v1/jobs?status=&cursor=&limit=`: newest first; `next_cursor` continues the listing.
pub async fn list(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    RawQuery(query): RawQuery,
) -> Result<impl IntoResponse, ApiError> {
    let q: ListQuery = parse_query(query.as_deref())?;
    if let Some(s) = &q.status
        && !STATUSES.contains(&s.as_str())
    {
        return Err(ApiError::invalid(
            "status",
            format!("unknown status {s:?}; one of {}", STATUSES.join(", ")),
        ));
    }
    let limit = q.limit.unwrap_or(20);
    if !(1..=100).contains(&limit) {
        return Err(ApiError::invalid(
            "limit",
            format!("limit {limit} is outside 1..=100"),
        ));
    }
    let before = match &q.cursor {
        None => i64::MAX,
        Some(c) => c.parse::<i64>().ok().filter(|v| *v > 0).ok_or_else(|| {
            ApiError::invalid(
                "cursor",
                "not a cursor returned as next_cursor by this route",
            )
        })?,
    };
    let mut jobs = state
        .store
        .list_jobs(&tenant, before, q.status.as_deref(), limit as i64 + 1)
        .await?;
    let next_cursor = if jobs.len() > limit as usize {
        jobs.truncate(limit as usize);
        jobs.last().map(|j| j.seq.to_string())
    } else {
        None
    };
    Ok(axum::Json(json!({
        "jobs": jobs.iter().map(JobRow::to_json).collect::<Vec<_>>(),
        "next_cursor": next_cursor,
    })))
}

async fn load(state: &AppState, tenant: &str, id: &str) -> Result<JobRow, ApiError> {
    state
        .store
        .get_job(tenant, id)
        .await?
        .ok_or_else(|| ApiError::not_found("job", id))
}

/// `GET /v1/jobs/{id}`.
pub async fn show(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(id): Path<String>,
) -> Result<impl IntoResponse, ApiError> {
    Ok(axum::Json(load(&state, &tenant, &id).await?.to_json()))
}

/// `POST /v1/jobs/{id}/cancel`: a queued job is cancelled at once (200); a running one stops within one
/// iteration (202); a finished one answers 409.
pub async fn cancel(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let status = match queue::cancel(&state, &tenant, &id).await? {
        CancelResult::NotFound => return Err(ApiError::not_found("job", &id)),
        CancelResult::AlreadyFinished(s) => {
            return Err(ApiError::conflict(
                "already_finished",
                format!("the job is already {s}"),
            ));
        }
        CancelResult::Cancelled => StatusCode::OK,
        CancelResult::Requested => StatusCode::ACCEPTED,
    };
    let job = load(&state, &tenant, &id).await?;
    Ok((status, axum::Json(job.to_json())).into_response())
}

/// `GET /v1/jobs/{id}/artifacts`.
pub async fn artifacts(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(id): Path<String>,
) -> Result<impl IntoResponse, ApiError> {
    load(&state, &tenant, &id).await?;
    let list: Vec<Value> = state
        .store
        .list_artifacts(&id)
        .await?
        .into_iter()
        .map(|a| {
            json!({
                "url": format!("/v1/jobs/{id}/artifacts/{}", a.name),
                "name": a.name,
                "content_type": a.content_type,
                "bytes": a.bytes,
                "sha256": a.sha256,
            })
        })
        .collect();
    Ok(axum::Json(json!({ "artifacts": list })))
}

/// A `Range` header's single byte range resolved against a length `total` (RFC 9110 §14.1.2):
/// `Some(Ok((first, last)))` inclusive; `Some(Err(()))` when unsatisfiable (416); `None` when the header is
/// absent or not one range of bytes, which is answered with the whole representation (a server may ignore
/// `Range`; several ranges are served whole rather than as multipart).
fn byte_range(header: Option<&str>, total: i64) -> Option<Result<(i64, i64), ()>> {
    let spec = header?.trim().strip_prefix("bytes=")?.trim();
    if spec.contains(',') {
        return None;
    }
    let (a, b) = spec.split_once('-')?;
    let (a, b) = (a.trim(), b.trim());
    let range = if a.is_empty() {
        // The last `n` bytes.
        let n: i64 = b.parse().ok()?;
        if n == 0 || total == 0 {
            return Some(Err(()));
        }
        (total.saturating_sub(n).max(0), total - 1)
    } else {
        let first: i64 = a.parse().ok()?;
        let last: i64 = if b.is_empty() {
            total - 1
        } else {
            let l: i64 = b.parse().ok()?;
            if l < first {
                return None;
            }
            l.min(total - 1)
        };
        if first >= total {
            return Some(Err(()));
        }
        (first, last)
    };
    Some(Ok(range))
}

/// Whether an `If-None-Match` header names `etag` (or is `*`), comparing weakly (RFC 9110 §13.1.2).
fn none_match(header: Option<&str>, etag: &str) -> bool {
    header.is_some_and(|h| {
        h.split(',')
            .map(str::trim)
            .any(|t| t == "*" || t.strip_prefix("W/").unwrap_or(t) == etag)
    })
}

/// The media type of bytes as such.
const OCTET_STREAM: &str = "application/octet-stream";

/// `GET /v1/jobs/{id}/artifacts/{name}`: the bytes, with their content type and an ETag of their SHA-256,
/// streamed from the database in chunks of [`CHUNK_BYTES`] (never held whole in memory). Downloads resume:
/// one byte range of `Range` is answered 206 with `Content-Range` (416 when it starts past the end;
/// `If-Range` with another ETag gets the whole artifact), and `If-None-Match` naming the ETag is answered
/// 304 without a body. `Accept: application/octet-stream` (without the artifact's own type) gets the same
/// bytes as that type.
pub async fn artifact(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path((id, name)): Path<(String, String)>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    load(&state, &tenant, &id).await?;
    let meta = state
        .store
        .artifact_meta(&id, &name)
        .await?
        .ok_or_else(|| ApiError::not_found("artifact", &name))?;
    let total = meta.bytes;
    let etag = format!("\"{}\"", meta.sha256);
    let text = |h: header::HeaderName| headers.get(h).and_then(|v| v.to_str().ok());
    let common = [
        (header::ETAG, etag.clone()),
        (header::ACCEPT_RANGES, "bytes".to_string()),
        (header::X_CONTENT_TYPE_OPTIONS, "nosniff".to_string()),
    ];
    if none_match(text(header::IF_NONE_MATCH), &etag) {
        return Ok((StatusCode::NOT_MODIFIED, common).into_response());
    }
    // `If-Range`: the range only while the artifact is still the one the client has part of.
    let range_applies = text(header::IF_RANGE).is_none_or(|v| v.trim() == etag);
    let range = if range_applies {
        byte_range(text(header::RANGE), total)
    } else {
        None
    };
    let (status, first, last) = match range {
        None => (StatusCode::OK, 0, total - 1),
        Some(Ok((a, b))) => (StatusCode::PARTIAL_CONTENT, a, b),
        Some(Err(())) => {
            let mut resp = ApiError::new(
                StatusCode::RANGE_NOT_SATISFIABLE,
                "range_not_satisfiable",
                format!("the artifact has {total} bytes; a Range must start before its end"),
            )
            .with_field("Range")
            .into_response();
            resp.headers_mut().insert(
                header::CONTENT_RANGE,
                header::HeaderValue::from_str(&format!("bytes */{total}"))
                    .map_err(ApiError::internal)?,
            );
            return Ok(resp);
        }
    };
    let disposition = format!("attachment; filename=\"{name}\"");
    // The same bytes as `application/octet-stream` to a client that asks for that and not the artifact's
    // own type (a generated client reading every artifact as bytes).
    let content_type = if accept_instead(&headers, OCTET_STREAM, &meta.content_type) {
        OCTET_STREAM.to_string()
    } else {
        meta.content_type
    };
    let end = last + 1;
    let chunks = async_stream::stream! {
        let mut offset = first;
        while offset < end {
            let len = CHUNK_BYTES.min(end - offset);
            match state.store.artifact_chunk(&id, &name, offset, len).await {
                Ok(chunk) if !chunk.is_empty() => {
                    offset += chunk.len() as i64;
                    yield Ok(Bytes::from(chunk));
                }
                Ok(_) => {
                    tracing::error!(job = %id, artifact = %name, offset, total, "artifact shorter than its size");
                    yield Err(std::io::Error::other("artifact shorter than its recorded size"));
                    break;
                }
                Err(e) => {
                    tracing::error!(job = %id, artifact = %name, error = %e, "reading an artifact failed");
                    yield Err(std::io::Error::other("reading the artifact failed"));
                    break;
                }
            }
        }
    };
    let mut resp = (
        status,
        common,
        [
            (header::CONTENT_TYPE, content_type),
            (header::CONTENT_DISPOSITION, disposition),
            (header::CONTENT_LENGTH, (end - first).max(0).to_string()),
        ],
        axum::body::Body::from_stream(chunks),
    )
        .into_response();
    if status == StatusCode::PARTIAL_CONTENT {
        resp.headers_mut().insert(
            header::CONTENT_RANGE,
            header::HeaderValue::from_str(&format!("bytes {first}-{last}/{total}"))
                .map_err(ApiError::internal)?,
        );
    }
    Ok(resp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_ranges_resolve_against_the_length() {
        assert_eq!(byte_range(None, 10), None);
        assert_eq!(byte_range(Some("bytes=2-4"), 10), Some(Ok((2, 4))));
        assert_eq!(byte_range(Some("bytes=2-"), 10), Some(Ok((2, 9))));
        assert_eq!(byte_range(Some("bytes=-3"), 10), Some(Ok((7, 9))));
        assert_eq!(byte_range(Some("bytes=-30"), 10), Some(Ok((0, 9))));
        assert_eq!(byte_range(Some("bytes=5-100"), 10), Some(Ok((5, 9))));
        assert_eq!(byte_range(Some("bytes=10-"), 10), Some(Err(())));
        assert_eq!(byte_range(Some("bytes=-0"), 10), Some(Err(())));
        // Not one range of bytes: the whole artifact.
        assert_eq!(byte_range(Some("bytes=0-1,4-5"), 10), None);
        assert_eq!(byte_range(Some("items=0-1"), 10), None);
        assert_eq!(byte_range(Some("bytes=4-2"), 10), None);
        assert_eq!(byte_range(Some("bytes=x-"), 10), None);
    }

    #[test]
    fn if_none_match_compares_weakly() {
        assert!(none_match(Some("\"ab\""), "\"ab\""));
        assert!(none_match(Some("W/\"ab\", \"cd\""), "\"ab\""));
        assert!(none_match(Some("*"), "\"ab\""));
        assert!(!none_match(Some("\"cd\""), "\"ab\""));
        assert!(!none_match(None, "\"ab\""));
    }
}
