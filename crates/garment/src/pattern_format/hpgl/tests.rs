//! Tests of the HP-GL/2 writer: a small plotter-side reader gets the cut lines back to a plotter unit.

use super::*;
use crate::pattern_format::test_pattern::bulged_tube_pattern;

/// What a plotter does with the file: strokes per pen (each from a `PU` to the last `PD`) and labels.
#[derive(Default, Debug)]
struct Plot {
    strokes: Vec<(u32, Vec<(i64, i64)>)>,
    labels: Vec<(u32, (i64, i64), String)>,
}

/// A small HP-GL/2 reader for the commands the writer uses (IN, DT, SP, SI, PU, PD, LB).
fn parse(file: &[u8]) -> Plot {
    let text = std::str::from_utf8(file).expect("ASCII");
    let mut plot = Plot::default();
    let (mut pen, mut at, mut terminator) = (0u32, (0i64, 0i64), '\u{3}');
    let mut rest = text;
    loop {
        rest = rest.trim_start_matches([';', '\n', ' ']);
        if rest.is_empty() {
            break;
        }
        let (cmd, args) = rest.split_at(2);
        if cmd == "LB" {
            let end = args.find(terminator).expect("label terminator");
            plot.labels.push((pen, at, args[..end].to_string()));
            rest = &args[end + terminator.len_utf8()..];
            continue;
        }
        let end = args.find(';').expect("command terminator");
        let params = &args[..end];
        rest = &args[end + 1..];
        let numbers = || -> Vec<i64> {
            if params.is_empty() {
                vec![]
            } else {
                params.split(',').map(|v| v.parse().unwrap()).collect()
            }
        };
        match cmd {
            "IN" | "SI" => {}
            "DT" => terminator = params.chars().next().unwrap(),
            "SP" => pen = params.parse().unwrap(),
            "PU" => {
                let v = numbers();
                if let [x, y, ..] = v[..] {
                    at = (x, y);
                }
                plot.strokes.push((pen, vec![at]));
            }
            "PD" => {
                let v = numbers();
                let s = &mut plot.strokes.last_mut().expect("PU before PD").1;
                for xy in v.chunks(2) {
                    at = (xy[0], xy[1]);
                    s.push(at);
                }
            }
            other => panic!("unexpected command {other}"),
        }
    }
    plot.strokes.retain(|(_, s)| s.len() > 1);
    plot
}

#[test]
fn hpgl_reads_back_the_cut_lines_to_a_plotter_unit() {
    let pattern = bulged_tube_pattern();
    let file = pattern_hpgl(&pattern);
    assert!(file.starts_with(b"IN;"));
    assert!(file.is_ascii());
    let plot = parse(&file);
    let layout = sheet(&pattern, GAP, MARGIN);
    let cut: Vec<&Vec<(i64, i64)>> = plot
        .strokes
        .iter()
        .filter(|(pen, _)| *pen == 1)
        .map(|(_, s)| s)
        .collect();
    assert_eq!(cut.len(), pattern.pieces.len());
    for ((piece, stroke), o) in pattern.pieces.iter().zip(cut).zip(&layout.offsets) {
        // Closed: back to the first point.
        assert_eq!(stroke.len(), piece.cut_line.len() + 1);
        assert_eq!(stroke.first(), stroke.last());
        for (&(x, y), q) in stroke.iter().zip(&piece.cut_line) {
            let want = (q + o) * 1000.0;
            let (dx, dy) = (x as Real / 40.0 - want.x, y as Real / 40.0 - want.y);
            assert!(dx.hypot(dy) <= 0.025, "({x}, {y}) vs {want:?} mm");
        }
    }
    let sew = plot.strokes.iter().filter(|(pen, _)| *pen == 2).count();
    assert_eq!(sew, pattern.pieces.len());
    let notches: usize = pattern.pieces.iter().map(|p| p.notches.len()).sum();
    // Notches, the grain line and its head per piece, on pen 3.
    let marks = plot.strokes.iter().filter(|(pen, _)| *pen == 3).count();
    assert_eq!(marks, notches + 2 * pattern.pieces.len());
    let texts: Vec<&str> = plot.labels.iter().map(|(_, _, t)| t.as_str()).collect();
    assert!(texts.contains(&"Piece: front"), "{texts:?}");
    assert!(texts.contains(&"Customer: Zoe Muller"), "{texts:?}");
    assert!(plot.labels.iter().all(|(pen, _, _)| *pen == 3));
}

#[test]
fn hpgl_survives_degenerate_models() {
    let mut pattern = bulged_tube_pattern();
    pattern.pieces[0].cut_line.clear();
    pattern.pieces[1].sewing_line.truncate(1);
    pattern.pieces[1].grain_line.to = pattern.pieces[1].grain_line.from;
    pattern.pieces[1].label_anchor.x = Real::NAN;
    pattern.pieces[0].name = "x;\u{3}y\nz".into();
    let plot = parse(&pattern_hpgl(&pattern));
    assert!(plot.labels.iter().any(|(_, _, t)| t == "Piece: x;yz"));
}
