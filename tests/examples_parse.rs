//! Every job in `examples/` parses and passes validation: scenes as scenes, `design_*.json` and
//! `order_*.json` as design jobs (`order_*_graded.json` as graded orders, one job per body)
//! (a renamed key or an out-of-range value would otherwise show only when someone runs the example).

use std::path::Path;

use skintight::design::DesignJob;
use skintight::knit::YarnScene;
use skintight::scene::Scene;

#[test]
fn every_example_job_parses_and_validates() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut checked = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("json") {
            continue;
        }
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if name.starts_with("order_") && name.ends_with("_graded.json") {
            match skintight::design::batch_from_file(&path) {
                Ok(Some(bodies)) => assert!(bodies.len() >= 2, "{name}: {} bodies", bodies.len()),
                Ok(None) => panic!("{name}: a graded order without `bodies`"),
                Err(e) => panic!("{name}: {e}"),
            }
        } else if name.starts_with("design_") || name.starts_with("order_") {
            if let Err(e) = DesignJob::from_file(&path) {
                panic!("{name}: {e}");
            }
        } else if let Err(e) = Scene::from_file(&path) {
            panic!("{name}: {e}");
        }
        checked += 1;
    }
    assert!(
        checked >= 20,
        "only {checked} examples found in {}",
        dir.display()
    );
}

/// Every yarn scene in `examples/knit/` parses, validates and names a pattern that exists (relative to the
/// scene, or a shared pattern in `../shared/data/yarns`), one per scenario at least.
#[test]
fn every_yarn_scene_example_parses_and_finds_its_pattern() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("examples/knit");
    let yarns = root.join("../shared/data/yarns");
    let mut scenarios = std::collections::BTreeSet::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("json") {
            continue;
        }
        let scene = YarnScene::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
        scenarios.insert(scene.scenario.name());
        if yarns.is_dir() {
            let pattern = scene.pattern_path(&dir, Some(&yarns));
            assert!(
                pattern.is_file(),
                "{}: {}",
                path.display(),
                pattern.display()
            );
        }
    }
    assert_eq!(
        scenarios.into_iter().collect::<Vec<_>>(),
        [
            "drape_sphere",
            "hang",
            "shear",
            "stretch_biaxial",
            "stretch_uniaxial"
        ]
    );
}
