//! Reading a JSON input (a scene, a design job, a request body) into a typed value, naming the field at
//! fault when it does not fit.
//!
//! serde reports where it stopped as a path (`garment.panels[2].name`, via `serde_path_to_error`); a
//! missing field and an unknown field are reported at their parent's path with the field's name in
//! backticks in the message, so [`error_key`] appends that name. The callers turn a [`JsonInputError`]
//! into their own error (a `SceneError` with the key, an HTTP 400/422 with the field).

use std::fmt;

/// Why a JSON input does not parse into the wanted type.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JsonInputError {
    /// Path of the field at fault (`a.b[3].c`, see [`error_key`]); empty for the document as a whole
    /// (malformed JSON, or a wrong type of the root).
    pub key: String,
    /// What is wrong, as serde_json says it, without the position (`invalid type: string "x", expected f64`).
    pub message: String,
    /// Line (1-based) where the parser stopped; 0 when unknown.
    pub line: usize,
    /// Column (1-based) where the parser stopped; 0 when unknown.
    pub column: usize,
    /// True when the text is not JSON at all (a syntax error or an unexpected end), false when it is JSON
    /// of the wrong shape (unknown key, wrong type, missing field, refused value).
    pub malformed: bool,
}

/// Displayed as serde_json displays its errors: `message at line L column C` (just the message when the
/// position is unknown).
impl fmt::Display for JsonInputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}", self.message)
        } else {
            write!(
                f,
                "{} at line {} column {}",
                self.message, self.line, self.column
            )
        }
    }
}

impl std::error::Error for JsonInputError {}

/// Parses the JSON text `bytes` into `T`. Unknown keys (where `T` denies them), wrong types, missing
/// required fields and values refused by `T`'s conversions are errors naming their key; malformed JSON
/// (and anything but white space after the document) is an error with `malformed` set and an empty key.
pub fn parse_json_input<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T, JsonInputError> {
    let de = &mut serde_json::Deserializer::from_slice(bytes);
    let value = serde_path_to_error::deserialize(&mut *de).map_err(|e| {
        let path = e.path().to_string();
        input_error(&path, e.into_inner())
    })?;
    // Nothing but white space may follow the document ("trailing characters").
    de.end().map_err(|e| input_error(".", e))?;
    Ok(value)
}

/// A serde_json error at `path` as a [`JsonInputError`].
fn input_error(path: &str, inner: serde_json::Error) -> JsonInputError {
    use serde_json::error::Category;
    let malformed = matches!(
        inner.classify(),
        Category::Syntax | Category::Eof | Category::Io
    );
    let (line, column) = (inner.line(), inner.column());
    let full = inner.to_string();
    // serde_json appends " at line L column C"; the key says where already.
    let suffix = format!(" at line {line} column {column}");
    let message = match full.strip_suffix(&suffix) {
        Some(m) if line != 0 => m.to_string(),
        _ => full,
    };
    let key = if malformed {
        String::new()
    } else {
        error_key(path, &message)
    };
    JsonInputError {
        key,
        message,
        line,
        column,
        malformed,
    }
}

/// The key of a serde error at `path` (as `serde_path_to_error` writes it) with `message`: serde reports a
/// missing field (and a field rejected by one of our conversions) at its parent's path, so the field named
/// in backticks (`` missing field `x` ``, `` unknown field `x` ``, `` duplicate field `x` ``) is appended;
/// `.` (the root) becomes empty.
pub fn error_key(path: &str, message: &str) -> String {
    let base = if path == "." { "" } else { path };
    let named = ["unknown field `", "missing field `", "duplicate field `"]
        .iter()
        .find_map(|p| {
            message
                .split_once(p)
                .and_then(|(_, rest)| rest.split_once('`'))
        })
        .map(|(name, _)| name);
    match named {
        // serde_path_to_error already ends the path of an unknown field with its name.
        Some(name) if base == name || base.ends_with(&format!(".{name}")) => base.to_string(),
        Some(name) if base.is_empty() => name.to_string(),
        Some(name) => format!("{base}.{name}"),
        None => base.to_string(),
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

    fn err(text: &str) -> JsonInputError {
        parse_json_input::<Outer>(text.as_bytes()).unwrap_err()
    }

    #[test]
    fn wrong_types_name_their_key() {
        let e = err(r#"{"kind":"a","inner":{"n":"x"}}"#);
        assert_eq!(e.key, "inner.n");
        assert!(!e.malformed);
        assert!(e.message.starts_with("invalid type: string \"x\""), "{e:?}");
        assert!(!e.message.contains(" at line "), "{e:?}");
        assert_eq!(e.line, 1);
        assert!(
            e.to_string()
                .ends_with(&format!(" at line 1 column {}", e.column))
        );
    }

    #[test]
    fn unknown_and_missing_fields_name_the_field() {
        assert_eq!(err(r#"{"kind":"a","inner":{"n":1,"m":2}}"#).key, "inner.m");
        assert_eq!(err(r#"{"inner":{"n":1}}"#).key, "kind");
        assert_eq!(err(r#"{"kind":"a","inner":{}}"#).key, "inner.n");
    }

    #[test]
    fn malformed_json_has_an_empty_key() {
        let e = err(r#"{"kind":"a","#);
        assert!(e.malformed);
        assert_eq!(e.key, "");
        let e = err("{kind}");
        assert!(e.malformed);
    }

    #[test]
    fn a_wrong_root_has_an_empty_key() {
        let e = err("42");
        assert!(!e.malformed);
        assert_eq!(e.key, "");
    }

    #[test]
    fn error_key_appends_the_named_field_once() {
        assert_eq!(error_key(".", "missing field `body`"), "body");
        assert_eq!(error_key("a.b", "missing field `c`"), "a.b.c");
        assert_eq!(error_key("a.c", "unknown field `c`, expected `d`"), "a.c");
        assert_eq!(error_key("a[2]", "invalid type"), "a[2]");
    }
}
