//! The text of the JSON files a job writes (`result.json`, `history.json`): objects indented one key a
//! line, as a reader skims them, and every array that holds no object on one line.
//!
//! Why: `result.json` carries per-element and per-vertex arrays (stretches, pressures, positions, …);
//! pretty-printed one number a line with its indentation, they made a knee-high order's `result.json`
//! 4.6 MB, about twice the same numbers on one line. Numbers are written as `serde_json` writes them
//! (shortest text that reads back to the same `f64`), so the file parses to the same value.

use serde_json::Value;

/// `value` as JSON text: objects (and arrays of objects) indented by two spaces a level, one entry a
/// line; arrays without objects in them on one line, compact.
pub fn json_text(value: &Value) -> Vec<u8> {
    let mut out = String::new();
    write(value, 0, &mut out);
    out.into_bytes()
}

/// Whether `value` is written over several lines.
fn spreads(value: &Value) -> bool {
    match value {
        Value::Object(map) => !map.is_empty(),
        Value::Array(items) => items.iter().any(spreads),
        _ => false,
    }
}

fn write(value: &Value, depth: usize, out: &mut String) {
    let indent = |out: &mut String, depth: usize| {
        out.push('\n');
        for _ in 0..depth {
            out.push_str("  ");
        }
    };
    match value {
        Value::Object(map) if !map.is_empty() => {
            out.push('{');
            for (k, (key, v)) in map.iter().enumerate() {
                if k > 0 {
                    out.push(',');
                }
                indent(out, depth + 1);
                out.push_str(&Value::String(key.clone()).to_string());
                out.push_str(": ");
                write(v, depth + 1, out);
            }
            indent(out, depth);
            out.push('}');
        }
        Value::Array(items) if spreads(value) => {
            out.push('[');
            for (k, v) in items.iter().enumerate() {
                if k > 0 {
                    out.push(',');
                }
                indent(out, depth + 1);
                write(v, depth + 1, out);
            }
            indent(out, depth);
            out.push(']');
        }
        other => out.push_str(&other.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// The text reads back to the same value, keeps number arrays on one line, and spreads objects.
    #[test]
    fn reads_back_the_same_with_number_arrays_on_one_line() {
        let value = json!({
            "a": [1.0, 0.1 + 0.2, -3e-310, 1e300],
            "nested": {"pairs": [[1, 2], [3, 4]], "empty": {}, "none": []},
            "list": [{"x": 1}, {"y": [true, null, "s\"q"]}],
            "text": "ü \n",
        });
        let text = String::from_utf8(json_text(&value)).unwrap();
        let back: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(back, value);
        assert!(
            text.contains("\"a\": [1.0,0.30000000000000004,-3e-310,1e+300]"),
            "{text}"
        );
        assert!(text.contains("\"pairs\": [[1,2],[3,4]]"), "{text}");
        assert!(
            text.contains("\n  \"list\": [\n    {\n      \"x\": 1\n    },"),
            "{text}"
        );
        assert!(text.contains("\"empty\": {}"), "{text}");
        // Smaller than serde_json's pretty text for a long number array (17-digit numbers: 19 bytes each
        // against 24 with the pretty text's indentation and line break), and on one line.
        let long = json!({"v": (0..1000).map(|i| i as f64 / 7.0).collect::<Vec<_>>()});
        let compact = json_text(&long);
        let pretty = serde_json::to_vec_pretty(&long).unwrap().len();
        assert!(
            compact.len() * 10 < pretty * 9,
            "{} not smaller than {pretty}",
            compact.len()
        );
        assert_eq!(compact.iter().filter(|&&b| b == b'\n').count(), 2);
    }
}
