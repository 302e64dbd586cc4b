//! The markup every figure of the report shares: escaping (the workspace's one [`escape`], re-exported from
//! the garment crate's `pattern_format::xml_text`), and numbers that say which `result.json` field
//! they show.
//!
//! **Numbers read back.** Each number taken from `result.json` is an element whose `data-field` is the
//! field's path in `result.json` — keys and array indices joined by dots, `regions.3.pressure_mmhg.mean` —
//! and whose text is the field's value times `data-scale` (1 when absent: 100 for m → cm, 10⁴ for m² →
//! cm², `1/PA_PER_MMHG` for Pa → mmHg) rounded to nearest at the decimals the text shows; a value in
//! scientific notation (`1.23e-4`) is rounded at its mantissa's decimals. A field that is `null` (or not
//! finite) reads `n/a`. Booleans and strings carry the JSON value in `data-value` (`true`, `false`, the
//! string); their text is for people. So a reader of the page (the headless-browser test) checks every
//! figure against `result.json` within half a unit of its last digit.

use std::fmt::Write;

pub use skintight_garment::pattern_format::xml_text::escape;

/// How a number is written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Digits {
    /// Fixed decimals.
    Fixed(usize),
    /// Scientific notation with this many mantissa decimals.
    Exp(usize),
}

/// `value × scale` written with `digits`, or `n/a` when not finite.
pub fn format_number(value: f64, scale: f64, digits: Digits) -> String {
    let v = value * scale;
    if !v.is_finite() {
        return "n/a".into();
    }
    let s = match digits {
        Digits::Fixed(d) => format!("{v:.d$}"),
        Digits::Exp(d) => format!("{v:.d$e}"),
    };
    // No negative zero.
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// `<tag data-field=… data-scale=…>value</tag>` for the `result.json` field at `path` holding `value`
/// (`None`: the JSON holds `null`), displayed as `value × scale` with `digits`.
pub fn field(tag: &str, path: &str, value: Option<f64>, scale: f64, digits: Digits) -> String {
    let mut out = format!("<{tag} data-field=\"{}\"", escape(path));
    if scale != 1.0 {
        let _ = write!(out, " data-scale=\"{scale:e}\"");
    }
    let text = value.map_or_else(|| "n/a".into(), |v| format_number(v, scale, digits));
    let _ = write!(out, ">{text}</{tag}>");
    out
}

/// A `<span>` [`field`].
pub fn num(path: &str, value: Option<f64>, scale: f64, digits: Digits) -> String {
    field("span", path, value, scale, digits)
}

/// A `<td>` [`field`].
pub fn num_td(path: &str, value: Option<f64>, scale: f64, digits: Digits) -> String {
    field("td", path, value, scale, digits)
}

/// `<tag data-field=… data-value=…>text</tag>` for a boolean or string field of `result.json`.
pub fn value_field(tag: &str, path: &str, value: &str, text: &str, class: &str) -> String {
    let class = if class.is_empty() {
        String::new()
    } else {
        format!(" class=\"{class}\"")
    };
    format!(
        "<{tag}{class} data-field=\"{}\" data-value=\"{}\">{}</{tag}>",
        escape(path),
        escape(value),
        escape(text)
    )
}

/// A colour of the result colour map (linear RGB in `[0, 1]`) as an sRGB `#rrggbb` for SVG and CSS.
pub fn srgb_hex(c: [f32; 3]) -> String {
    let enc = |x: f32| {
        let x = x.clamp(0.0, 1.0) as f64;
        let s = if x <= 0.003_130_8 {
            12.92 * x
        } else {
            1.055 * x.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round() as u8
    };
    format!("#{:02x}{:02x}{:02x}", enc(c[0]), enc(c[1]), enc(c[2]))
}

/// `s` with the entities [`escape`] writes (and `&nbsp;`) decoded.
fn unescape(s: &str) -> String {
    s.replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&#39;", "'")
        .replace("&nbsp;", "\u{a0}")
        .replace("&amp;", "&")
}

/// The value of attribute `name` in the attribute text `attrs` of one tag.
fn attribute(attrs: &str, name: &str) -> Option<String> {
    let key = format!(" {name}=\"");
    let at = attrs.find(&key)? + key.len();
    let end = attrs[at..].find('"')? + at;
    Some(unescape(&attrs[at..end]))
}

/// The JSON value at the dotted `path` (`regions.3.pressure_mmhg.mean`).
fn lookup<'a>(json: &'a serde_json::Value, path: &str) -> Option<&'a serde_json::Value> {
    path.split('.').try_fold(json, |v, key| match v {
        serde_json::Value::Array(a) => a.get(key.parse::<usize>().ok()?),
        serde_json::Value::Object(o) => o.get(key),
        _ => None,
    })
}

/// Whether the displayed `text` is `value × scale` rounded as the text shows (module documentation).
fn number_matches(text: &str, value: f64, scale: f64) -> bool {
    let Ok(shown) = text.parse::<f64>() else {
        return false;
    };
    let (mantissa, exp) = match text.split_once(['e', 'E']) {
        Some((m, e)) => (m, e.parse::<i32>().unwrap_or(0)),
        None => (text, 0),
    };
    let decimals = mantissa.split_once('.').map_or(0, |(_, d)| d.len()) as i32;
    let tolerance = 0.5 * 10f64.powi(exp - decimals);
    let expected = value * scale;
    (shown - expected).abs() <= tolerance * (1.0 + 1e-9) + 1e-12 * expected.abs()
}

/// Reads back every marked number and value of a report page (`html`: the file, or a browser's
/// serialization of its DOM) and checks it against `result` (the job's `result.json`, with
/// `prescription` when the report shows one): the count of fields checked, or the first mismatch naming
/// the field.
pub fn read_back(html: &str, result: &serde_json::Value) -> Result<usize, String> {
    let mut checked = 0;
    let mut rest = html;
    while let Some(k) = rest.find(" data-field=\"") {
        let tag_start = rest[..k].rfind('<').ok_or("a data-field outside a tag")?;
        let tag_end = k + rest[k..].find('>').ok_or("an unclosed tag")?;
        let attrs = &rest[tag_start..tag_end];
        let path = attribute(attrs, "data-field").ok_or("an empty data-field")?;
        let text_end = rest[tag_end + 1..]
            .find('<')
            .map_or(rest.len(), |e| tag_end + 1 + e);
        let text = unescape(rest[tag_end + 1..text_end].trim());
        rest = &rest[tag_end + 1..];
        let json = lookup(result, &path)
            .ok_or_else(|| format!("{path}: shown in the report but not in result.json"))?;
        if let Some(value) = attribute(attrs, "data-value") {
            let expected = match json {
                serde_json::Value::String(s) => s.clone(),
                serde_json::Value::Null => "null".into(),
                other => other.to_string(),
            };
            if value != expected {
                return Err(format!(
                    "{path}: the report says {value:?}, result.json {expected:?}"
                ));
            }
        } else if text == "n/a" {
            if !json.is_null() {
                return Err(format!("{path}: the report says n/a, result.json {json}"));
            }
        } else {
            let scale = match attribute(attrs, "data-scale") {
                Some(s) => s
                    .parse::<f64>()
                    .map_err(|_| format!("{path}: data-scale {s:?} is not a number"))?,
                None => 1.0,
            };
            let value = json
                .as_f64()
                .ok_or_else(|| format!("{path}: the report shows {text:?}, result.json {json}"))?;
            if !number_matches(&text, value, scale) {
                return Err(format!(
                    "{path}: the report shows {text:?}, result.json {value} (× {scale})"
                ));
            }
        }
        checked += 1;
    }
    Ok(checked)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_name_their_field_and_round() {
        assert_eq!(
            num("regions.0.girth_m", Some(0.23456), 100.0, Digits::Fixed(1)),
            "<span data-field=\"regions.0.girth_m\" data-scale=\"1e2\">23.5</span>"
        );
        assert_eq!(
            num_td("residual", Some(1.234e-7), 1.0, Digits::Exp(2)),
            "<td data-field=\"residual\">1.23e-7</td>"
        );
        assert_eq!(
            num("x", None, 1.0, Digits::Fixed(1)),
            "<span data-field=\"x\">n/a</span>"
        );
        assert_eq!(format_number(f64::NAN, 1.0, Digits::Fixed(1)), "n/a");
        assert_eq!(format_number(-0.01, 1.0, Digits::Fixed(1)), "0.0");
        assert_eq!(
            value_field("b", "admissible", "false", "no <ok>", "bad"),
            "<b class=\"bad\" data-field=\"admissible\" data-value=\"false\">no &lt;ok&gt;</b>"
        );
        assert_eq!(srgb_hex([0.0, 1.0, 0.5]), "#00ffbc");
    }

    #[test]
    fn read_back_checks_every_field_and_can_fail() {
        let json = serde_json::json!({"a": {"b": [0.5, 2.0e-7]}, "ok": false, "name": "C&D", "none": null});
        let page = format!(
            "<p>{} {} {} {} {}</p>",
            num("a.b.0", Some(0.5), 100.0, Digits::Fixed(1)),
            num("a.b.1", Some(2.0e-7), 1.0, Digits::Exp(2)),
            value_field("b", "ok", "false", "no", ""),
            value_field("i", "name", "C&D", "C&D", ""),
            num("none", None, 1.0, Digits::Fixed(1)),
        );
        assert_eq!(read_back(&page, &json), Ok(5));
        // Within half a unit of the last digit, and no more.
        assert!(number_matches("50.0", 0.50049, 100.0));
        assert!(!number_matches("50.0", 0.5006, 100.0));
        assert!(number_matches("1.23e-4", 1.2349e-4, 1.0));
        assert!(!number_matches("1.23e-4", 1.236e-4, 1.0));
        for (bad, what) in [
            (page.replace(">50.0<", ">50.2<"), "a.b.0"),
            (
                page.replace("data-value=\"false\"", "data-value=\"true\""),
                "ok",
            ),
            (page.replace("a.b.1", "a.b.7"), "a.b.7"),
            (page.replace(">n/a<", ">0.0<"), "none"),
        ] {
            let e = read_back(&bad, &json).unwrap_err();
            assert!(e.starts_with(what), "{e}");
        }
    }
}
