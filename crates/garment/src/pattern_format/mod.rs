//! The files a cutting room reads, each written from the one [`Pattern`](crate::pattern::Pattern) model:
//!
//! - [`mod@json`]: `patterns.json`, the whole model, versioned (`schema_version`), in millimetres;
//! - [`mod@garmentcode`]: the same pieces and stitches in GarmentCode's JSON pattern specification;
//! - [`mod@svg`]: a true-scale SVG drawing with one layer per kind of line;
//! - [`mod@dxf`]: `patterns.dxf` (DXF-AAMA) and `patterns-astm.dxf` (DXF-ASTM), one block per piece on the
//!   AAMA/ASTM layers;
//! - [`mod@pdf`]: `patterns.pdf` (one wide page at 1:1) and `patterns-a4.pdf` (tiled onto A4, Letter or A3);
//! - [`mod@hpgl`]: `patterns.plt`, HP-GL/2 for plotters and cutters;
//! - [`mod@xml_text`]: text escaped for XML and HTML (the SVG here, the app's HTML report).
//!
//! Every writer draws the pieces side by side as [`sheet`](crate::pattern::sheet) lays them out.

pub mod dxf;
pub mod garmentcode;
pub mod hpgl;
pub mod json;
pub mod pdf;
pub mod svg;
pub mod xml_text;

#[cfg(test)]
pub(crate) mod test_pattern;
#[cfg(any(test, feature = "test-support"))]
pub mod verify;

/// `text` in printable ASCII, for formats whose readers take nothing else (DXF-AAMA/ASTM readers, HP-GL
/// plotters): control characters dropped, Latin letters with diacritics folded to their base letters
/// (`Zoë Müller` → `Zoe Muller`, `ß` → `ss`), a few typographic marks to their ASCII look-alikes, anything
/// else `?`.
pub(crate) fn ascii_text(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars().filter(|c| !c.is_control()) {
        let folded = match c {
            ' '..='~' => {
                out.push(c);
                continue;
            }
            'À'..='Å' => "A",
            'Æ' => "AE",
            'Ç' => "C",
            'È'..='Ë' => "E",
            'Ì'..='Ï' => "I",
            'Ð' => "D",
            'Ñ' => "N",
            'Ò'..='Ö' | 'Ø' => "O",
            '×' => "x",
            'Ù'..='Ü' => "U",
            'Ý' => "Y",
            'Þ' => "Th",
            'ß' => "ss",
            'à'..='å' => "a",
            'æ' => "ae",
            'ç' => "c",
            'è'..='ë' => "e",
            'ì'..='ï' => "i",
            'ð' => "d",
            'ñ' => "n",
            'ò'..='ö' | 'ø' => "o",
            '÷' => "/",
            'ù'..='ü' => "u",
            'ý' | 'ÿ' => "y",
            'þ' => "th",
            'Œ' => "OE",
            'œ' => "oe",
            'Š' => "S",
            'š' => "s",
            'Ž' => "Z",
            'ž' => "z",
            'Ł' => "L",
            'ł' => "l",
            '\u{a0}' => " ",
            '–' | '—' => "-",
            '‘' | '’' => "'",
            '“' | '”' => "\"",
            '°' => " deg",
            '€' => "EUR",
            _ => "?",
        };
        out.push_str(folded);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::ascii_text;

    #[test]
    fn ascii_text_folds_diacritics_and_drops_control_characters() {
        assert_eq!(ascii_text("Zoë Müller\u{3}\n"), "Zoe Muller");
        assert_eq!(ascii_text("Straße – Œuvre"), "Strasse - OEuvre");
        assert_eq!(ascii_text("✂ 日本"), "? ??");
        assert!(ascii_text("any ✂ text\u{7f}").is_ascii());
    }
}
