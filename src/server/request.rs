//! Reading request inputs into typed values, naming the input at fault: query strings and bodies. (JSON
//! bodies: [`super::error::parse_json`].)

use axum::extract::rejection::BytesRejection;
use axum::http::StatusCode;

use super::asset_budget::BudgetRefusal;
use super::error::{ApiError, field_of};

/// The answer to a read of a mesh that did not get its share of the server's budget
/// (`server.asset_check_memory_bytes`): 422 naming `field` when it could never fit, 429 with
/// `Retry-After` when the budget stayed taken.
pub fn budget_error(refusal: BudgetRefusal, field: &str) -> ApiError {
    match refusal {
        BudgetRefusal::TooLarge { charge, budget } => ApiError::invalid(
            field,
            format!(
                "reading this mesh would take about {charge} bytes of the server's memory, more than the \
                 {budget} bytes of its budget for that (a quarter of server.asset_check_memory_bytes for \
                 the files, the rest for their parses); send a smaller mesh"
            ),
        ),
        BudgetRefusal::Busy { waited_s } => {
            let retry = waited_s.max(1);
            let mut e = ApiError::new(
                StatusCode::TOO_MANY_REQUESTS,
                "busy",
                format!(
                    "the server is reading other meshes and has no memory free for this one \
                     (server.asset_check_memory_bytes); retry in {retry} s"
                ),
            );
            e.retry_after_s = Some(retry);
            e
        }
    }
}

/// Parses a query string into `T`, naming the parameter at fault.
pub fn parse_query<T: serde::de::DeserializeOwned + Default>(
    raw: Option<&str>,
) -> Result<T, ApiError> {
    let Some(raw) = raw.filter(|r| !r.is_empty()) else {
        return Ok(T::default());
    };
    let de = serde_urlencoded::Deserializer::new(form_urlencoded::parse(raw.as_bytes()));
    serde_path_to_error::deserialize::<_, T>(de).map_err(|e| {
        let path = e.path().to_string();
        let msg = e.into_inner().to_string();
        let field = field_of(&path, &msg);
        ApiError::invalid(field, format!("query parameter: {msg}"))
    })
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

/// Whether the request's `Accept` asks for `wanted` and not for `own` (media types compared without their
/// parameters, case-insensitively; an entry with `q=0` asks for nothing): the answer then carries `wanted`
/// as its type instead of its own, with the same bytes (an artifact as `application/octet-stream`, this
/// document as `text/yaml`).
pub fn accept_instead(headers: &axum::http::HeaderMap, wanted: &str, own: &str) -> bool {
    let named = headers
        .get_all(axum::http::header::ACCEPT)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .filter_map(|entry| {
            let mut parts = entry.split(';').map(str::trim);
            let media = parts.next()?.to_ascii_lowercase();
            let refused = parts.any(|p| {
                p.strip_prefix("q=")
                    .and_then(|q| q.parse::<f64>().ok())
                    .is_some_and(|q| q <= 0.0)
            });
            (!refused).then_some(media)
        });
    let own = own.split(';').next().unwrap_or(own).trim();
    let (mut wants, mut owns) = (false, false);
    for m in named {
        wants |= m == wanted;
        owns |= m.eq_ignore_ascii_case(own);
    }
    wants && !owns
}

#[cfg(test)]
mod tests {
    use super::accept_instead;
    use axum::http::{HeaderMap, HeaderValue, header::ACCEPT};

    fn accept(v: &str) -> HeaderMap {
        let mut h = HeaderMap::new();
        h.insert(ACCEPT, HeaderValue::from_str(v).unwrap());
        h
    }

    #[test]
    fn accept_names_the_type_asked_for_instead_of_its_own() {
        let bin = "application/octet-stream";
        assert!(accept_instead(&accept(bin), bin, "model/gltf-binary"));
        assert!(accept_instead(
            &accept("Application/Octet-Stream;q=0.9, */*;q=0.1"),
            bin,
            "model/gltf-binary"
        ));
        // Its own type named too, refused, or not asked: its own type.
        assert!(!accept_instead(
            &accept("model/gltf-binary, application/octet-stream"),
            bin,
            "model/gltf-binary"
        ));
        assert!(!accept_instead(
            &accept("application/octet-stream;q=0"),
            bin,
            "text/html"
        ));
        assert!(!accept_instead(&accept("*/*"), bin, "text/html"));
        assert!(!accept_instead(&HeaderMap::new(), bin, "text/html"));
        assert!(!accept_instead(
            &accept("application/octet-stream, text/html; charset=utf-8"),
            bin,
            "text/html; charset=utf-8"
        ));
    }
}
