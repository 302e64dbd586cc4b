//! Job routes: submit (with `Idempotency-Key`), list (newest first, cursor pagination), show, cancel, and
//! artifacts.

use std::collections::BTreeMap;

use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, RawQuery, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use serde_json::{Value, json};
use sqlx::Row;

use super::AppState;
use super::assets::{body_error, parse_query, sha256_hex};
use super::auth::Tenant;
use super::error::{ApiError, parse_json};
use super::queue::{self, CancelResult, JobRow, job_columns};
use super::runner::Assets;

/// Body of `POST /v1/jobs`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SubmitJob {
    kind: String,
    spec: Value,
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

/// `POST /v1/jobs`.
pub async fn submit(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let body = body.map_err(|r| body_error(r, state.config.server.max_json_bytes))?;
    let key = idempotency_key(&headers)?;
    let req: SubmitJob = parse_json(&body)?;
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
    let runner = state.registry.get(&req.kind).ok_or_else(|| {
        ApiError::invalid(
            "kind",
            format!(
                "unknown job kind {:?}; this server runs: {}",
                req.kind,
                state.registry.kinds().join(", ")
            ),
        )
    })?;
    runner
        .validate(&req.spec)
        .map_err(|e| ApiError::invalid(format!("spec.{}", e.field), e.message))?;
    let mut assets = Assets::default();
    for r in runner.assets(&req.spec) {
        let Some(asset) = super::assets::load(&state.pool, &tenant, &r.id).await? else {
            return Err(ApiError::new(
                StatusCode::UNPROCESSABLE_ENTITY,
                "unknown_asset",
                format!(
                    "no asset with id {:?}; upload it with POST /v1/assets first",
                    r.id
                ),
            )
            .with_field(format!("spec.{}", r.field)));
        };
        assets.by_field.insert(r.field, asset);
    }
    if !assets.by_field.is_empty() {
        // Reading a mesh takes a while: off the async runtime's threads.
        let (check_runner, spec) = (runner.clone(), req.spec.clone());
        tokio::task::spawn_blocking(move || check_runner.check_assets(&spec, &assets))
            .await
            .map_err(ApiError::internal)?
            .map_err(|e| ApiError::invalid(format!("spec.{}", e.field), e.message))?;
    }
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

    let id = uuid::Uuid::now_v7().to_string();
    let mut tx = state.pool.begin_with("BEGIN IMMEDIATE").await?;
    let inserted = sqlx::query(
        "INSERT INTO jobs (id, tenant, kind, spec, idempotency_key, request_hash, status) \
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, 'queued')",
    )
    .bind(&id)
    .bind(&tenant)
    .bind(&req.kind)
    .bind(&spec_text)
    .bind(&key)
    .bind(&hash)
    .execute(&mut *tx)
    .await;
    match inserted {
        Ok(_) => {}
        // A concurrent request with the same key won the race: answer as a replay.
        Err(sqlx::Error::Database(e)) if e.is_unique_violation() && key.is_some() => {
            tx.rollback().await?;
            let key = key.as_deref().unwrap_or_default();
            return replay(&state, &tenant, key, &hash).await?.ok_or_else(|| {
                ApiError::internal("idempotency key conflict without a stored job")
            });
        }
        Err(e) => return Err(e.into()),
    }
    queue::append_event(&mut tx, &id, "queued", &json!({ "kind": req.kind })).await?;
    tx.commit().await?;
    state.bump_events();
    state.job_available.notify_one();
    let job = queue::get_job(&state.pool, &tenant, &id)
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

/// An earlier submission with the same idempotency key: the same job (200) when the request was the same,
/// 409 when it differed.
async fn replay(
    state: &AppState,
    tenant: &str,
    key: &str,
    hash: &str,
) -> Result<Option<Response>, ApiError> {
    let row = sqlx::query(concat!(
        "SELECT request_hash, ",
        job_columns!(),
        " FROM jobs WHERE tenant = ?1 AND idempotency_key = ?2"
    ))
    .bind(tenant)
    .bind(key)
    .fetch_optional(&state.pool)
    .await?;
    let Some(row) = row else { return Ok(None) };
    let stored: String = row.try_get("request_hash")?;
    if stored != hash {
        return Err(ApiError::new(
            StatusCode::CONFLICT,
            "idempotency_key_reused",
            "this Idempotency-Key was already used with a different request body",
        )
        .with_field("Idempotency-Key"));
    }
    let job = JobRow::from_row(&row)?;
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

const STATUSES: &[&str] = &["queued", "running", "completed", "failed", "cancelled"];

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
    let rows = sqlx::query(concat!(
        "SELECT ",
        job_columns!(),
        " FROM jobs WHERE tenant = ?1 AND seq < ?2 AND (?3 IS NULL OR status = ?3) ORDER BY seq DESC LIMIT ?4"
    ))
    .bind(&tenant)
    .bind(before)
    .bind(&q.status)
    .bind(limit as i64 + 1)
    .fetch_all(&state.pool)
    .await?;
    let mut jobs = rows
        .iter()
        .map(JobRow::from_row)
        .collect::<Result<Vec<_>, _>>()?;
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
    queue::get_job(&state.pool, tenant, id)
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
    let status = match queue::cancel(&state.pool, &tenant, &id).await? {
        CancelResult::NotFound => return Err(ApiError::not_found("job", &id)),
        CancelResult::AlreadyFinished(s) => {
            return Err(ApiError::conflict(
                "already_finished",
                format!("the job is already {s}"),
            ));
        }
        CancelResult::Cancelled => {
            state.bump_events();
            StatusCode::OK
        }
        CancelResult::Requested => {
            if let Some(flags) = state.running.lock().expect("running map").get(&id) {
                flags
                    .cancel
                    .store(true, std::sync::atomic::Ordering::SeqCst);
            }
            StatusCode::ACCEPTED
        }
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
    let rows = sqlx::query(
        "SELECT name, content_type, bytes, sha256 FROM artifacts WHERE job_id = ?1 ORDER BY name",
    )
    .bind(&id)
    .fetch_all(&state.pool)
    .await?;
    let list = rows
        .iter()
        .map(|r| -> Result<Value, sqlx::Error> {
            let name: String = r.try_get("name")?;
            Ok(json!({
                "name": name,
                "content_type": r.try_get::<String, _>("content_type")?,
                "bytes": r.try_get::<i64, _>("bytes")?,
                "sha256": r.try_get::<String, _>("sha256")?,
                "url": format!("/v1/jobs/{id}/artifacts/{name}"),
            }))
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(axum::Json(json!({ "artifacts": list })))
}

/// `GET /v1/jobs/{id}/artifacts/{name}`: the bytes, with their content type and an ETag of their SHA-256.
pub async fn artifact(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path((id, name)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    load(&state, &tenant, &id).await?;
    let row = sqlx::query(
        "SELECT content_type, sha256, data FROM artifacts WHERE job_id = ?1 AND name = ?2",
    )
    .bind(&id)
    .bind(&name)
    .fetch_optional(&state.pool)
    .await?
    .ok_or_else(|| ApiError::not_found("artifact", &name))?;
    let content_type: String = row.try_get("content_type")?;
    let sha: String = row.try_get("sha256")?;
    let data: Vec<u8> = row.try_get("data")?;
    Ok((
        [
            (header::CONTENT_TYPE, content_type),
            (header::ETAG, format!("\"{sha}\"")),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"{name}\""),
            ),
        ],
        data,
    )
        .into_response())
}
