//! Checks of the pattern files with the tools their users use — ezdxf (Python) for DXF, pdftoppm (poppler)
//! for PDF — and the small readers they need, shared by this crate's tests and the application's. A missing
//! tool skips its check with a note, except in CI (`CI=true`), where it fails.
//!
//! Compiled for tests and with the `test-support` feature.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::math::Real;
use crate::pattern_format::pdf::TEST_SQUARE_MM;

/// Whether the tests run in CI (`CI=true`), where every outside checker must be there.
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// Skips a check whose tool is missing: a note outside CI, a failure in CI.
pub fn missing(check: &str, why: &str) {
    assert!(!in_ci(), "CI=true but {check} cannot run: {why}");
    eprintln!("note: skipping {check}: {why}");
}

/// A Python interpreter that has a module.
pub struct Python(PathBuf);

/// The interpreter in `SKINTIGHT_PYTHON` if it imports `module`; `None` (after [`missing`]) otherwise.
pub fn python_with(module: &str, check: &str) -> Option<Python> {
    let Some(path) = std::env::var_os("SKINTIGHT_PYTHON").filter(|p| !p.is_empty()) else {
        missing(
            check,
            "SKINTIGHT_PYTHON is not set (a Python with ezdxf; .ci/run makes one)",
        );
        return None;
    };
    let ok = Command::new(&path)
        .args(["-c", &format!("import {module}")])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        missing(
            check,
            &format!("SKINTIGHT_PYTHON={path:?} cannot import {module}"),
        );
        return None;
    }
    Some(Python(path.into()))
}

impl Python {
    /// Runs `python -c script args…` and parses its standard output as JSON; panics with its standard
    /// error if it fails.
    pub fn run(&self, script: &str, args: &[&str]) -> serde_json::Value {
        let out = Command::new(&self.0)
            .arg("-c")
            .arg(script)
            .args(args)
            .output()
            .expect("run python");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "python failed: {stderr}");
        if !stderr.trim().is_empty() {
            eprintln!("python: {stderr}");
        }
        serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
            panic!(
                "python printed no JSON ({e}): {}",
                String::from_utf8_lossy(&out.stdout)
            )
        })
    }
}

/// Whether `program` is on `PATH`.
pub fn on_path(program: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|dir| is_file(&dir.join(program))))
}

fn is_file(path: &Path) -> bool {
    path.is_file()
}

/// A fresh scratch folder for one test (removed by the test when it passes).
pub fn scratch_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "skintight-pattern-format-{tag}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Page objects in a PDF (`/Type /Page`, not `/Pages`).
pub fn page_count(pdf: &[u8]) -> usize {
    let key = b"/Type /Page";
    pdf.windows(key.len() + 1)
        .filter(|w| &w[..key.len()] == key && !w[key.len()].is_ascii_alphanumeric())
        .count()
}

/// A binary PGM (`P5`, 8 bit) as width, height and rows of gray values.
pub fn read_pgm(bytes: &[u8]) -> (usize, usize, Vec<u8>) {
    read_pnm(bytes, "P5", 1)
}

/// A binary PGM or PPM (`magic` `P5` or `P6`, 8 bit, `channels` values a pixel) as width, height and rows.
fn read_pnm(bytes: &[u8], magic: &str, channels: usize) -> (usize, usize, Vec<u8>) {
    let mut fields = Vec::new();
    let mut i = 0;
    while fields.len() < 4 {
        while bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        if bytes[i] == b'#' {
            while bytes[i] != b'\n' {
                i += 1;
            }
            continue;
        }
        let start = i;
        while !bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        fields.push(String::from_utf8_lossy(&bytes[start..i]).to_string());
    }
    assert_eq!(fields[0], magic);
    let (w, h): (usize, usize) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
    assert_eq!(fields[3], "255");
    (w, h, bytes[i + 1..i + 1 + w * h * channels].to_vec())
}

/// Centre (px) of the dark line crossing `samples` between `from` and `to`: the darkness-weighted mean.
fn line_centre(samples: impl Fn(usize) -> u8, from: usize, to: usize) -> Real {
    let (mut sum, mut weight) = (0.0, 0.0);
    for i in from..to {
        let dark = 255.0 - samples(i) as Real;
        if dark > 20.0 {
            sum += dark * (i as Real + 0.5);
            weight += dark;
        }
    }
    assert!(weight > 0.0, "no line between px {from} and {to}");
    sum / weight
}

/// Renders page `page` of `pdf` with pdftoppm at `dpi` and measures the test square whose top-left
/// corner should be `(left, top)` mm from the page's top-left corner: its width and height (mm)
/// between the centres of its edges.
pub fn measure_square(pdf: &[u8], page: usize, dpi: Real, left: Real, top: Real) -> (Real, Real) {
    let dir = scratch_dir(&format!("pdftoppm-{page}-{}", pdf.len()));
    std::fs::write(dir.join("page.pdf"), pdf).unwrap();
    let page_arg = page.to_string();
    let status = std::process::Command::new("pdftoppm")
        .args(["-r", &dpi.to_string(), "-f", &page_arg, "-l", &page_arg])
        .args(["-gray", "-singlefile"])
        .arg(dir.join("page.pdf"))
        .arg(dir.join("page"))
        .status()
        .expect("run pdftoppm");
    assert!(status.success());
    let (w, _, px) = read_pgm(&std::fs::read(dir.join("page.pgm")).unwrap());
    let _ = std::fs::remove_dir_all(&dir);
    let mm_to_px = dpi / 25.4;
    let px_of = |mm: Real| (mm * mm_to_px).round() as usize;
    let window = 8.0;
    // Horizontally, along the square's middle row.
    let row = px_of(top + 0.5 * TEST_SQUARE_MM);
    let at_row = |x: usize| px[row * w + x];
    let l = line_centre(at_row, px_of(left - window), px_of(left + window));
    let r = line_centre(
        at_row,
        px_of(left + TEST_SQUARE_MM - window),
        px_of(left + TEST_SQUARE_MM + window),
    );
    // Vertically, along a column clear of the square's caption.
    let col = px_of(left + 0.75 * TEST_SQUARE_MM);
    let at_col = |y: usize| px[y * w + col];
    let t = line_centre(at_col, px_of(top - window), px_of(top + window));
    let b = line_centre(
        at_col,
        px_of(top + TEST_SQUARE_MM - window),
        px_of(top + TEST_SQUARE_MM + window),
    );
    ((r - l) / mm_to_px, (b - t) / mm_to_px)
}

/// Renders every page of `pdf` with pdftoppm at `dpi` in colour and counts, per page, the pixels of the
/// pieces' fill (the cut lines' light tint, `rgb(246, 241, 231)`: red at least 235 and at least 8 above
/// blue; neutral paper, black and grey lines and blue marks are not counted).
pub fn fill_pixels_per_page(pdf: &[u8], dpi: Real) -> Vec<usize> {
    let dir = scratch_dir(&format!("pdftoppm-fill-{}", pdf.len()));
    std::fs::write(dir.join("doc.pdf"), pdf).unwrap();
    let status = std::process::Command::new("pdftoppm")
        .args(["-r", &dpi.to_string()])
        .arg(dir.join("doc.pdf"))
        .arg(dir.join("page"))
        .status()
        .expect("run pdftoppm");
    assert!(status.success());
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ppm"))
        .collect();
    // page-1.ppm … or page-01.ppm …: the same digit count, so names sort as numbers.
    files.sort();
    let counts = files
        .iter()
        .map(|f| {
            let (_, _, rgb) = read_pnm(&std::fs::read(f).unwrap(), "P6", 3);
            rgb.chunks_exact(3)
                .filter(|p| p[0] >= 235 && i32::from(p[0]) >= i32::from(p[2]) + 8)
                .count()
        })
        .collect();
    let _ = std::fs::remove_dir_all(&dir);
    counts
}

/// Reads the DXF file `argv[1]`, audits it and prints, as JSON, the audit's error count, `$INSUNITS`
/// and per INSERTed piece block the count of cut lines (POLYLINE on 1), notches (LINE on 4), grain
/// lines (LINE on 7), sew lines (POLYLINE on 14) and ASTM boundaries (POLYLINE on 84), with the first cut
/// line's points (`cut`) and the grain line's ends (`grain`) in drawing coordinates (mm: the INSERT's point
/// added), and the vertices of the POLYLINEs on layer `FABRIC` of the drawing (`fabric`, a marker's edges).
pub const EZDXF_CHECK: &str = r#"
import json, sys
import ezdxf
doc = ezdxf.readfile(sys.argv[1])
auditor = doc.audit()
for e in auditor.errors:
    print(e, file=sys.stderr)
pieces = []
for ins in doc.modelspace().query("INSERT"):
    blk = doc.blocks[ins.dxf.name]
    at = ins.dxf.insert
    cut = [[v.dxf.location.x + at.x, v.dxf.location.y + at.y]
           for p in blk.query('POLYLINE[layer=="1"]')[:1] for v in p.vertices]
    grain = [[[l.dxf.start.x + at.x, l.dxf.start.y + at.y], [l.dxf.end.x + at.x, l.dxf.end.y + at.y]]
             for l in blk.query('LINE[layer=="7"]')[:1]]
    pieces.append({
        "cut": cut,
        "grain": grain[0] if grain else None,
        "1": len(blk.query('POLYLINE[layer=="1"]')),
        "4": len(blk.query('LINE[layer=="4"]')),
        "7": len(blk.query('LINE[layer=="7"]')),
        "14": len(blk.query('POLYLINE[layer=="14"]')),
        "84": len(blk.query('POLYLINE[layer=="84"]')),
    })
print(json.dumps({
    "errors": len(auditor.errors),
    "fixes": len(auditor.fixes),
    "insunits": doc.header.get("$INSUNITS"),
    "pieces": pieces,
    "fabric": [[[v.dxf.location.x, v.dxf.location.y] for v in p.vertices]
               for p in doc.modelspace().query('POLYLINE[layer=="FABRIC"]')],
}))
"#;

/// The text strings of a PDF's content streams, decoded: literal `(…)` strings (with their escapes) and
/// hexadecimal `<…>` strings, bytes read as Latin-1 (what WinAnsi is for the letters this writer uses).
/// Enough to read back what this crate's PDF writer wrote (uncompressed streams).
pub fn pdf_strings(pdf: &[u8]) -> Vec<String> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < pdf.len() {
        match pdf[i] {
            b'(' => {
                let mut s = String::new();
                let mut depth = 1;
                i += 1;
                while i < pdf.len() && depth > 0 {
                    match pdf[i] {
                        b'\\' if i + 1 < pdf.len() => {
                            i += 1;
                            s.push(match pdf[i] {
                                b'n' => '\n',
                                b'r' => '\r',
                                b't' => '\t',
                                c => c as char,
                            });
                        }
                        b'(' => {
                            depth += 1;
                            s.push('(');
                        }
                        b')' => {
                            depth -= 1;
                            if depth > 0 {
                                s.push(')');
                            }
                        }
                        c => s.push(c as char),
                    }
                    i += 1;
                }
                out.push(s);
            }
            b'<' if pdf.get(i + 1) != Some(&b'<') && i > 0 && pdf[i - 1] != b'<' => {
                let end = pdf[i..]
                    .iter()
                    .position(|&c| c == b'>')
                    .map_or(pdf.len(), |e| i + e);
                let hex: Vec<u8> = pdf[i + 1..end]
                    .iter()
                    .copied()
                    .filter(u8::is_ascii_hexdigit)
                    .collect();
                let s: String = hex
                    .chunks(2)
                    .filter_map(|p| u8::from_str_radix(std::str::from_utf8(p).ok()?, 16).ok())
                    .map(char::from)
                    .collect();
                out.push(s);
                i = end + 1;
            }
            _ => i += 1,
        }
    }
    out
}
