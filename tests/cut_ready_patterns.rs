//! Issue 17's acceptance on the pants: one `skintight simulate examples/pants.json` writes every pattern file,
//! the seams sew (both sides equal to 0.5 mm, notches at the same arc lengths), and each file reads back with
//! the tool its users use.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use skintight_garment::pattern::Pattern;
use skintight_garment::pattern_format::pdf::{Paper, tiled_test_square};
use skintight_garment::pattern_format::verify;

const EXE: &str = env!("CARGO_BIN_EXE_skintight");

/// The pants simulated once for every test of this file (about 40 s).
fn pants() -> &'static Path {
    static OUT: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    &OUT.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("pants");
        let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/pants.json");
        let res = Command::new(EXE)
            .args(["simulate", "--quiet"])
            .arg(&scene)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            res.status.success(),
            "{}",
            String::from_utf8_lossy(&res.stderr)
        );
        (dir, out)
    })
    .1
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

#[test]
fn pants_seams_sew_and_their_notches_match() {
    let out = pants();
    let result = read_json(&out.join("result.json"));
    let seams = result["seams"].as_array().unwrap();
    assert_eq!(seams.len(), 6, "{}", result["seams"]);
    for s in seams {
        let lengths: Vec<f64> = s["lengths_mm"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let difference = s["difference_mm"].as_f64().unwrap();
        assert!(difference.abs() < 0.5, "{s}");
        assert!((lengths[0] - lengths[1] - difference).abs() < 1e-9);
        assert!(lengths[0] > 150.0, "{s}");
    }
    // The flattening alone left them millimetres apart: truing did the work.
    let truing = &result["seam_truing"];
    assert!(
        truing["max_seam_mismatch_before_mm"].as_f64().unwrap() > 1.0,
        "{truing}"
    );
    assert!(
        truing["max_seam_mismatch_after_mm"].as_f64().unwrap() < 1e-3,
        "{truing}"
    );

    let patterns = read_json(&out.join("patterns.json"));
    assert_eq!(patterns["schema_version"], 1);
    let pieces = patterns["pieces"].as_array().unwrap();
    assert_eq!(pieces.len(), 4);
    for (k, s) in patterns["seams"].as_array().unwrap().iter().enumerate() {
        let arcs: Vec<Vec<f64>> = (0..2)
            .map(|side| {
                let piece = &pieces[s["panels"][side].as_u64().unwrap() as usize];
                piece["notches"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .filter(|n| n["seam"].as_u64() == Some(k as u64))
                    .map(|n| n["arc_length_mm"].as_f64().unwrap())
                    .collect()
            })
            .collect();
        assert_eq!(arcs[0], arcs[1], "seam {k}");
        // Ends plus every 10 cm.
        let length = s["lengths_mm"][0].as_f64().unwrap();
        assert_eq!(
            arcs[0].len(),
            2 + ((length - 50.0) / 100.0).floor() as usize,
            "seam {k}"
        );
    }
    for piece in pieces {
        let names: Vec<&str> = piece["edges"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["name"].as_str().unwrap())
            .collect();
        assert!(
            names.contains(&"top opening") && names.contains(&"bottom opening"),
            "{names:?}"
        );
        let allowance: Vec<f64> = piece["edges"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["allowance_mm"].as_f64().unwrap())
            .collect();
        assert!(
            allowance.contains(&6.0) && allowance.contains(&20.0),
            "{allowance:?}"
        );
    }
}

#[test]
fn pants_write_every_pattern_file() {
    let out = pants();
    for (file, magic) in [
        ("patterns.svg", &b"<?xml"[..]),
        ("patterns.json", b"{"),
        ("patterns-garmentcode.json", b"{"),
        ("patterns.dxf", b"  0\r\nSECTION"),
        ("patterns-astm.dxf", b"  0\r\nSECTION"),
        ("patterns.pdf", b"%PDF-"),
        ("patterns-a4.pdf", b"%PDF-"),
        ("patterns.plt", b"IN;"),
        ("patterns-marker.pdf", b"%PDF-"),
        ("patterns-marker.dxf", b"  0\r\nSECTION"),
    ] {
        let bytes = std::fs::read(out.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(
            bytes.starts_with(magic),
            "{file} starts {:?}",
            String::from_utf8_lossy(&bytes[..bytes.len().min(16)])
        );
    }
}

/// ezdxf audits both DXF files of the pants to 0 errors and finds, per piece, its outline on layer 1, its
/// notches on layer 4, its grain line on layer 7 and its sew line on layer 14.
#[test]
fn pants_dxf_files_pass_the_ezdxf_audit_with_their_layers() {
    let Some(python) = verify::python_with("ezdxf", "the ezdxf audit of the pants' DXF files")
    else {
        return;
    };
    let out = pants();
    let patterns = read_json(&out.join("patterns.json"));
    let pieces = patterns["pieces"].as_array().unwrap();
    for file in ["patterns.dxf", "patterns-astm.dxf"] {
        let report = python.run(verify::EZDXF_CHECK, &[out.join(file).to_str().unwrap()]);
        eprintln!("ezdxf {file}: {report}");
        assert_eq!(report["errors"], 0, "{file}: {report}");
        let blocks = report["pieces"].as_array().unwrap();
        assert_eq!(blocks.len(), pieces.len(), "{file}: {report}");
        for (b, piece) in blocks.iter().zip(pieces) {
            assert_eq!(b["1"], 1, "{file}: {report}");
            assert_eq!(
                b["4"],
                piece["notches"].as_array().unwrap().len(),
                "{file}: {report}"
            );
            assert_eq!(b["7"], 1, "{file}: {report}");
            assert_eq!(b["14"], 1, "{file}: {report}");
        }
    }
}

/// The tiled A4 PDF of the pants has the pages its key says (1 + the printed tiles, read from the tiles'
/// text) and its test square measures 100 mm in a pdftoppm render at the PDF's scale.
#[test]
fn pants_tiled_pdf_has_its_pages_and_a_true_test_square() {
    let out = pants();
    let pdf = std::fs::read(out.join("patterns-a4.pdf")).unwrap();
    // Every tile carries "row r / col c - page p of N"; the largest r and c give the grid.
    let keys: Vec<(usize, usize, usize)> = verify::pdf_strings(&pdf)
        .iter()
        .filter(|s| s.starts_with("row "))
        .filter_map(|s| {
            let w: Vec<&str> = s
                .split(|c: char| !c.is_ascii_digit())
                .filter(|w| !w.is_empty())
                .collect();
            Some((
                w.first()?.parse().ok()?,
                w.get(1)?.parse().ok()?,
                w.get(3)?.parse().ok()?,
            ))
        })
        .collect();
    assert!(!keys.is_empty(), "no tile keys found");
    let rows = keys.iter().map(|k| k.0).max().unwrap();
    let cols = keys.iter().map(|k| k.1).max().unwrap();
    let total = keys[0].2;
    // One page per printed tile after the key; tiles that meet no piece are left out of the grid.
    assert_eq!(total, 1 + keys.len(), "{keys:?}");
    assert!(total <= 1 + rows * cols, "{keys:?}");
    assert_eq!(verify::page_count(&pdf), total);
    if !verify::on_path("pdftoppm") {
        verify::missing(
            "the pdftoppm render of the pants' patterns-a4.pdf",
            "pdftoppm is not on PATH",
        );
        return;
    }
    // Where the square is: the tiles start at the drawing's top-left corner, where the square sits, so its
    // place on the first tile page does not depend on the pieces.
    let empty = Pattern {
        labels: Default::default(),
        pieces: vec![],
        seams: vec![],
    };
    let (page, left, top) = tiled_test_square(&empty, Paper::A4);
    let (w, h) = verify::measure_square(&pdf, page, 150.0, left, top);
    eprintln!("pants patterns-a4.pdf page {page} at 150 dpi: test square {w:.3} × {h:.3} mm");
    assert!(
        (w - 100.0).abs() <= 0.5 && (h - 100.0).abs() <= 0.5,
        "{w} × {h} mm"
    );
}
