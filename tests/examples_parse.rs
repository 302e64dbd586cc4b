//! Every job in `examples/` parses and passes validation: scenes as scenes, `design_*.json` and
//! `order_*.json` as design jobs
//! (a renamed key or an out-of-range value would otherwise show only when someone runs the example).

use std::path::Path;

use skintight::design::DesignJob;
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
        if name.starts_with("design_") || name.starts_with("order_") {
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
