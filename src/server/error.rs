//! The one error type of the HTTP API and its JSON envelope:
//! `{"error": {"code": "...", "message": "...", "field": "..."}}` (`field` only where one input is at fault).
//! Details of server-side failures (5xx) are logged with the request's id, never sent.

use axum::Json;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde::Serialize;

/// An error answered to the client.
#[derive(Debug)]
pub struct ApiError {
    pub status: StatusCode,
    /// Stable machine-readable code, e.g. `invalid_field`, `not_found`.
    pub code: &'static str,
    /// Human-readable explanation.
    pub message: String,
    /// The input at fault: a JSON path in the body (`spec.iterations`), a query parameter, a header.
    pub field: Option<String>,
    /// Seconds to wait before retrying, sent as `Retry-After` (429, 503).
    pub retry_after_s: Option<u64>,
}

#[derive(Serialize)]
struct Envelope<'a> {
    error: Body<'a>,
}

#[derive(Serialize)]
struct Body<'a> {
    code: &'a str,
    message: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    field: Option<&'a str>,
}

impl ApiError {
    pub fn new(status: StatusCode, code: &'static str, message: impl Into<String>) -> Self {
        ApiError {
            status,
            code,
            message: message.into(),
            field: None,
            retry_after_s: None,
        }
    }

    pub fn with_field(mut self, field: impl Into<String>) -> Self {
        self.field = Some(field.into());
        self
    }

    /// 422: a well-formed request whose named input is not acceptable.
    pub fn invalid(field: impl Into<String>, message: impl Into<String>) -> Self {
        ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, "invalid_field", message).with_field(field)
    }

    /// 400: a request that cannot be parsed at all.
    pub fn bad_request(code: &'static str, message: impl Into<String>) -> Self {
        ApiError::new(StatusCode::BAD_REQUEST, code, message)
    }

    /// 404 for an unknown id or one that belongs to another tenant (the two are indistinguishable).
    pub fn not_found(what: &str, id: &str) -> Self {
        ApiError::new(
            StatusCode::NOT_FOUND,
            "not_found",
            format!("no {what} with id {id:?}"),
        )
    }

    pub fn conflict(code: &'static str, message: impl Into<String>) -> Self {
        ApiError::new(StatusCode::CONFLICT, code, message)
    }

    pub fn too_large(field: impl Into<String>, message: impl Into<String>) -> Self {
        ApiError::new(StatusCode::PAYLOAD_TOO_LARGE, "too_large", message).with_field(field)
    }

    pub fn unauthorized(message: impl Into<String>) -> Self {
        ApiError::new(StatusCode::UNAUTHORIZED, "unauthorized", message)
    }

    /// 500: the cause is logged here and replaced by a generic message.
    pub fn internal(cause: impl std::fmt::Display) -> Self {
        tracing::error!(error = %cause, "internal error");
        ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            "internal",
            "internal server error; the details are in the server log",
        )
    }

    pub fn unavailable(message: impl Into<String>) -> Self {
        ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "unavailable", message)
    }
}

impl From<sqlx::Error> for ApiError {
    fn from(e: sqlx::Error) -> Self {
        ApiError::internal(format!("database: {e}"))
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = Envelope {
            error: Body {
                code: self.code,
                message: &self.message,
                field: self.field.as_deref(),
            },
        };
        let mut resp = (self.status, Json(body)).into_response();
        if let Some(s) = self.retry_after_s {
            resp.headers_mut().insert(
                axum::http::header::RETRY_AFTER,
                axum::http::HeaderValue::from(s),
            );
        }
        if self.status == StatusCode::UNAUTHORIZED {
            resp.headers_mut().insert(
                axum::http::header::WWW_AUTHENTICATE,
                axum::http::HeaderValue::from_static("Bearer"),
            );
        }
        resp
    }
}

/// Deserializes a JSON body into `T`, naming the field at fault: the JSON path of a wrong type or value,
/// `parent.name` of an unknown field, and the line/column of malformed JSON.
pub fn parse_json<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    crate::json_input::parse_json_input(bytes).map_err(|e| {
        if e.malformed {
            ApiError::bad_request("malformed_json", format!("the body is not valid JSON: {e}"))
                .with_field("body")
        } else {
            let field = if e.key.is_empty() {
                "body".to_string()
            } else {
                e.key.clone()
            };
            // The message as serde_json writes it, position included.
            ApiError::invalid(field, e.to_string())
        }
    })
}

/// The path of the input at fault ([`crate::json_input::error_key`]); the body as a whole is `body`.
pub fn field_of(path: &str, msg: &str) -> String {
    let key = crate::json_input::error_key(path, msg);
    if key.is_empty() {
        "body".to_string()
    } else {
        key
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(serde::Deserialize, Debug)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Outer {
        kind: String,
        inner: Inner,
    }
    #[derive(serde::Deserialize, Debug)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Inner {
        n: u32,
    }

    #[test]
    fn json_errors_name_the_field() {
        let e = parse_json::<Outer>(br#"{"kind":"a","inner":{"n":"x"}}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("inner.n"));
        assert_eq!(e.status, StatusCode::UNPROCESSABLE_ENTITY);
        let e = parse_json::<Outer>(br#"{"kind":"a","inner":{"n":1,"m":2}}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("inner.m"));
        let e = parse_json::<Outer>(br#"{"inner":{"n":1}}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("kind"));
        let e = parse_json::<Outer>(br#"{"kind":"a","#).unwrap_err();
        assert_eq!(e.status, StatusCode::BAD_REQUEST);
        assert_eq!(e.code, "malformed_json");
        // Anything after the document, and a key given twice.
        let e = parse_json::<Outer>(br#"{"kind":"a","inner":{"n":1}} {"x":1}"#).unwrap_err();
        assert_eq!(
            (e.status, e.field.as_deref()),
            (StatusCode::BAD_REQUEST, Some("body"))
        );
        parse_json::<Outer>(b"{\"kind\":\"a\",\"inner\":{\"n\":1}} \n").unwrap();
        let e = parse_json::<Outer>(br#"{"kind":"a","kind":"b","inner":{"n":1}}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("kind"), "{e:?}");
    }
}
