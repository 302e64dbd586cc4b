//! A design order graded over several bodies: `bodies: [{"name": …, <body>}, …]` in place of `body`
//! (docs/DESIGN_JOB.md). Each body makes one ordinary design job — the order with `body` set to that
//! entry without its `name` — designed on its own, its files under the body's name (a folder of the CLI's
//! `--out`, an artifact prefix `NAME/` in the service). A shop grades one garment over a team or a size run
//! with one order.
//!
//! Checked before any body is designed, each error naming its key: `bodies` and `body` not both; `bodies`
//! a non-empty list of at most [`MAX_BATCH_BODIES`] objects; every `name` a file-like name
//! (`[A-Za-z0-9._-]`, 1–64 characters, not starting with a dot) used once; and every body's job valid,
//! its errors at `bodies[i]…` where the one-body job says `body…`.

use serde_json::Value;

use super::spec::DesignJob;
use crate::json_input::parse_json_input;
use crate::scene::SceneError;

/// Most bodies in one order.
pub const MAX_BATCH_BODIES: usize = 64;

/// One body of a graded order: its name and its design job.
#[derive(Clone, Debug, PartialEq)]
pub struct BatchBody {
    /// The body's name in the order (`bodies[i].name`): its output folder or artifact prefix.
    pub name: String,
    /// The order with this body.
    pub job: DesignJob,
}

/// Whether `name` can name a body's folder and artifact prefix: 1–64 of `[A-Za-z0-9._-]`, not starting
/// with a dot.
pub fn valid_body_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && !name.starts_with('.')
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'.' || b == b'_' || b == b'-')
}

/// The key `key` of the one-body job of `bodies[index]` as the order names it: `body…` becomes
/// `bodies[index]…`; other keys stay.
pub fn batch_key(key: &str, index: usize) -> String {
    match key.strip_prefix("body") {
        Some(rest) if rest.is_empty() || rest.starts_with('.') || rest.starts_with('[') => {
            format!("bodies[{index}]{rest}")
        }
        _ => key.to_string(),
    }
}

/// The bodies of the design order `text` when it has `bodies` (each checked as a design job, see the module
/// notes), or `None` for a one-body order (read it with [`DesignJob::from_json`]).
pub fn batch_from_json(text: &str) -> Result<Option<Vec<BatchBody>>, SceneError> {
    let order: Value = parse_json_input(text.as_bytes())
        .map_err(|e| SceneError::from_json_input(e, "design job"))?;
    let Some(object) = order.as_object() else {
        return Ok(None);
    };
    let Some(bodies) = object.get("bodies") else {
        return Ok(None);
    };
    if object.contains_key("body") {
        return Err(SceneError::new(
            "bodies",
            "give either `body` (one body) or `bodies` (a list of named bodies), not both",
        ));
    }
    let list = bodies.as_array().ok_or_else(|| {
        SceneError::new(
            "bodies",
            "must be a list of bodies, each a body object with a `name`",
        )
    })?;
    if list.is_empty() {
        return Err(SceneError::new(
            "bodies",
            "the list is empty: give at least one body (or one `body`)",
        ));
    }
    if list.len() > MAX_BATCH_BODIES {
        return Err(SceneError::new(
            "bodies",
            format!(
                "{} bodies: at most {MAX_BATCH_BODIES} in one order; split the order",
                list.len()
            ),
        ));
    }
    let mut out: Vec<BatchBody> = Vec::with_capacity(list.len());
    for (i, entry) in list.iter().enumerate() {
        let mut body = entry.as_object().cloned().ok_or_else(|| {
            SceneError::new(
                format!("bodies[{i}]"),
                "must be a body object (`source`, …) with a `name`",
            )
        })?;
        let name = match body.remove("name") {
            Some(Value::String(n)) if valid_body_name(&n) => n,
            Some(other) => {
                return Err(SceneError::new(
                    format!("bodies[{i}].name"),
                    format!(
                        "{other} cannot name the body's folder: use 1–64 letters, digits, '.', '_' \
                         or '-', not starting with '.'"
                    ),
                ));
            }
            None => {
                return Err(SceneError::new(
                    format!("bodies[{i}].name"),
                    "missing: every body of `bodies` needs a name (its output folder)",
                ));
            }
        };
        if let Some(j) = out.iter().position(|b| b.name == name) {
            return Err(SceneError::new(
                format!("bodies[{i}].name"),
                format!("'{name}' is already the name of bodies[{j}]: give each body its own name"),
            ));
        }
        let mut one = object.clone();
        one.remove("bodies");
        one.insert("body".into(), Value::Object(body));
        let job = DesignJob::from_json(&Value::Object(one).to_string())
            .map_err(|e| SceneError::new(batch_key(&e.key, i), e.message))?;
        out.push(BatchBody { name, job });
    }
    Ok(Some(out))
}

/// [`batch_from_json`] of the file at `path`; errors name the file.
pub fn batch_from_file(path: &std::path::Path) -> Result<Option<Vec<BatchBody>>, SceneError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| SceneError::new("", format!("cannot read {}: {e}", path.display())))?;
    batch_from_json(&text)
        .map_err(|e| SceneError::new(e.key, format!("{}: {}", path.display(), e.message)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn order() -> Value {
        let text = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("examples/order_knee_high_class1.json"),
        )
        .unwrap();
        serde_json::from_str(&text).unwrap()
    }

    fn batch(bodies: Value) -> Value {
        let mut o = order();
        let body = o.as_object_mut().unwrap().remove("body").unwrap();
        let list: Vec<Value> = bodies
            .as_array()
            .unwrap()
            .iter()
            .map(|b| {
                let mut e = body.clone();
                for (k, v) in b.as_object().unwrap() {
                    e[k] = v.clone();
                }
                e
            })
            .collect();
        o["bodies"] = Value::Array(list);
        o
    }

    fn error(order: &Value) -> SceneError {
        batch_from_json(&order.to_string()).unwrap_err()
    }

    #[test]
    fn a_graded_order_makes_one_job_per_body_in_order() {
        let mut o = batch(json!([{"name": "anna"}, {"name": "ben-2"}]));
        o["bodies"][1]["source"]["path"] = "../../shared/data/bodies/male_1k.obj".into();
        let bodies = batch_from_json(&o.to_string()).unwrap().unwrap();
        let names: Vec<&str> = bodies.iter().map(|b| b.name.as_str()).collect();
        assert_eq!(names, ["anna", "ben-2"]);
        let single = DesignJob::from_json(&order().to_string()).unwrap();
        assert_eq!(bodies[0].job, single);
        assert_ne!(bodies[1].job.body, single.body);
        assert_eq!(bodies[1].job.garment, single.garment);
        // A one-body order is not a batch.
        assert_eq!(batch_from_json(&order().to_string()).unwrap(), None);
    }

    #[test]
    fn bad_batches_name_their_key() {
        let mut both = batch(json!([{"name": "a"}]));
        both["body"] = order()["body"].clone();
        let cases = [
            (batch(json!([])), "bodies", "empty"),
            (both, "bodies", "not both"),
            (
                batch(json!([{"name": "a"}, {"name": "b"}, {"name": "a"}])),
                "bodies[2].name",
                "already the name of bodies[0]",
            ),
            (batch(json!([{"name": "a/b"}])), "bodies[0].name", "letters"),
            (batch(json!([{"name": ".x"}])), "bodies[0].name", "letters"),
            (batch(json!([{"name": 3}])), "bodies[0].name", "letters"),
            (
                batch(
                    json!([{"name": "a"}, {"name": "b", "source": {"kind": "surface_mesh", "path": "x.obj", "thickness": -1.0}}]),
                ),
                "bodies[1].source",
                "",
            ),
            (
                batch(json!([{"name": "a"}, {"name": "b", "material": {"youngs_modulus": -5.0}}])),
                "bodies[1].material.youngs_modulus",
                "",
            ),
            (
                batch(json!([{"name": "a"}, {"name": "b", "colour": "red"}])),
                "bodies[1].colour",
                "",
            ),
        ];
        for (o, key, words) in cases {
            let e = error(&o);
            assert!(e.key.starts_with(key), "{key}: {e}");
            assert!(e.message.contains(words), "{key}: {e}");
        }
        let mut unnamed = batch(json!([{"name": "a"}]));
        unnamed["bodies"][0].as_object_mut().unwrap().remove("name");
        assert_eq!(error(&unnamed).key, "bodies[0].name");
        let mut not_list = order();
        not_list["bodies"] = json!({"a": 1});
        not_list.as_object_mut().unwrap().remove("body");
        assert_eq!(error(&not_list).key, "bodies");
        let many: Vec<Value> = (0..=MAX_BATCH_BODIES)
            .map(|i| json!({"name": format!("b{i}")}))
            .collect();
        assert_eq!(error(&batch(Value::Array(many))).key, "bodies");
        // Keys outside the body stay as they are.
        let mut o = batch(json!([{"name": "a"}]));
        o["optimizer"]["max_iterations"] = json!(0);
        assert!(error(&o).key.starts_with("optimizer"), "{}", error(&o));
    }

    #[test]
    fn body_keys_become_the_entry_keys() {
        assert_eq!(batch_key("body", 2), "bodies[2]");
        assert_eq!(batch_key("body.source.path", 0), "bodies[0].source.path");
        assert_eq!(batch_key("bodywork", 0), "bodywork");
        assert_eq!(batch_key("garment.template", 1), "garment.template");
    }
}
