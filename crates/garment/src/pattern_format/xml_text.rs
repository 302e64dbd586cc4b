//! Text for XML and HTML documents (the SVG pattern drawing, the app's HTML report and its inline SVG
//! figures): the five markup characters written as entities, so that any text can stand in character data
//! and in a double- or single-quoted attribute value: `&` → `&amp;`, `<` → `&lt;`, `>` → `&gt;`,
//! `"` → `&quot;`, `'` → `&#39;` (the numeric form, which every XML and HTML reader knows; `&apos;` is not
//! in HTML 4). Control characters other than tab, line feed and carriage return are dropped: XML 1.0 does
//! not allow them at all and HTML counts them as parse errors.
//!
//! One function for every document the workspace writes, in the lowest crate its users share, so that a
//! name a customer typed reads the same on the pattern and in the report.

/// `text` with `&`, `<`, `>`, `"` and `'` escaped and control characters (but tab, LF, CR) dropped, for
/// XML/HTML character data and attribute values.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c if (c as u32) < 0x20 && c != '\t' && c != '\n' && c != '\r' => {}
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markup_and_control_characters() {
        assert_eq!(
            escape("A & B <c> \"d\" 'e'\u{7}\tf\n"),
            "A &amp; B &lt;c&gt; &quot;d&quot; &#39;e&#39;\tf\n"
        );
        assert_eq!(escape("Zoë"), "Zoë");
    }
}
