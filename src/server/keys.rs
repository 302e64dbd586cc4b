//! API keys: `Authorization: Bearer <key>`. Each configured key acts for one tenant, which sees only its own
//! assets and jobs (another tenant's ids answer 404). Operator keys may read `/metrics`. With
//! `auth.disabled = true` (allowed only on a loopback address) every request acts for the tenant `default`
//! and `/metrics` is open.
//!
//! The extractors [`Tenant`] and [`Operator`] need only the [`Keys`]: they work with any router state `S`
//! that hands out an `Arc<Keys>` (`Arc<Keys>: FromRef<S>`, as [`super::state::AppState`] does).

use std::sync::Arc;

use axum::extract::{FromRef, FromRequestParts};
use axum::http::request::Parts;
use sha2::{Digest, Sha256};

use super::config::AuthConfig;
use super::error::ApiError;

/// The tenant every request acts for when authentication is disabled.
pub const DEFAULT_TENANT: &str = "default";

/// Configured keys, stored as SHA-256 digests and compared in constant time.
pub struct Keys {
    disabled: bool,
    tenants: Vec<([u8; 32], String)>,
    operators: Vec<[u8; 32]>,
}

fn digest(key: &str) -> [u8; 32] {
    Sha256::digest(key.as_bytes()).into()
}

fn ct_eq(a: &[u8; 32], b: &[u8; 32]) -> bool {
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

impl Keys {
    pub fn from_config(c: &AuthConfig) -> Keys {
        Keys {
            disabled: c.disabled,
            tenants: c
                .keys
                .iter()
                .map(|k| (digest(&k.key), k.tenant.clone()))
                .collect(),
            operators: c.operator_keys.iter().map(|k| digest(k)).collect(),
        }
    }

    fn tenant_of(&self, token: &str) -> Option<&str> {
        let d = digest(token);
        // Check every key (no early exit) so timing does not reveal which one matched.
        let mut found = None;
        for (k, tenant) in &self.tenants {
            if ct_eq(k, &d) {
                found = Some(tenant.as_str());
            }
        }
        found
    }

    fn is_operator(&self, token: &str) -> bool {
        let d = digest(token);
        self.operators
            .iter()
            .fold(false, |acc, k| acc | ct_eq(k, &d))
    }
}

fn bearer(parts: &Parts) -> Result<&str, ApiError> {
    let value = parts
        .headers
        .get(axum::http::header::AUTHORIZATION)
        .ok_or_else(|| ApiError::unauthorized("missing Authorization: Bearer <API key> header"))?;
    let text = value
        .to_str()
        .map_err(|_| ApiError::unauthorized("the Authorization header is not ASCII"))?;
    let (scheme, token) = text.split_once(' ').ok_or_else(|| {
        ApiError::unauthorized("the Authorization header must be `Bearer <API key>`")
    })?;
    if !scheme.eq_ignore_ascii_case("bearer") || token.trim().is_empty() {
        return Err(ApiError::unauthorized(
            "the Authorization header must be `Bearer <API key>`",
        ));
    }
    Ok(token.trim())
}

/// The tenant a request acts for.
#[derive(Debug, Clone)]
pub struct Tenant(pub String);

impl<S> FromRequestParts<S> for Tenant
where
    S: Send + Sync,
    Arc<Keys>: FromRef<S>,
{
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        let keys = Arc::<Keys>::from_ref(state);
        if keys.disabled {
            return Ok(Tenant(DEFAULT_TENANT.to_string()));
        }
        let token = bearer(parts)?;
        keys.tenant_of(token)
            .map(|t| Tenant(t.to_string()))
            .ok_or_else(|| ApiError::unauthorized("unknown API key"))
    }
}

/// A request made with an operator key.
#[derive(Debug, Clone)]
pub struct Operator;

impl<S> FromRequestParts<S> for Operator
where
    S: Send + Sync,
    Arc<Keys>: FromRef<S>,
{
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        let keys = Arc::<Keys>::from_ref(state);
        if keys.disabled {
            return Ok(Operator);
        }
        let token = bearer(parts)?;
        if keys.is_operator(token) {
            Ok(Operator)
        } else if keys.tenant_of(token).is_none() {
            // A key the server does not know at all: not authenticated (a tenant's key is, but may not).
            Err(ApiError::unauthorized("unknown API key"))
        } else {
            Err(ApiError::new(
                axum::http::StatusCode::FORBIDDEN,
                "forbidden",
                "this route needs an operator key",
            ))
        }
    }
}
