//! The README's service walk-through stays runnable: the job it submits (the here-document between the
//! `walkthrough-job` marker comments) is a valid `simulate` request on the body scan it uploads, and it is the
//! scene of `examples/calf_sleeve.json`.

use serde_json::Value;
use skintight::server::simulate_job::SimulateJob;
use skintight::server::{Asset, AssetRef, Assets, JobRunner};

const README: &str = include_str!("../README.md");
const BEGIN: &str = "<!-- walkthrough-job:begin -->";
const END: &str = "<!-- walkthrough-job:end -->";
/// What the walk-through's shell puts where the asset id goes.
const ASSET_VAR: &str = "$ASSET";

/// The text of the here-document (`cat > FILE <<EOF` … `EOF`) between the markers.
fn walkthrough_job() -> String {
    let start = README.find(BEGIN).expect("README has the begin marker") + BEGIN.len();
    let len = README[start..]
        .find(END)
        .expect("README has the end marker");
    let block = &README[start..start + len];
    let mut lines = block
        .lines()
        .skip_while(|l| !l.trim_end().ends_with("<<EOF"));
    assert!(
        lines.next().is_some(),
        "no `<<EOF` here-document between the markers:\n{block}"
    );
    let body: Vec<&str> = lines.take_while(|l| l.trim_end() != "EOF").collect();
    assert!(!body.is_empty(), "empty here-document:\n{block}");
    body.join("\n")
}

fn body_asset() -> Asset {
    let bodies = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join("shared/data/bodies"))
        .find(|d| d.is_dir())
        .expect("shared/data/bodies next to the checkout");
    Asset {
        id: ASSET_VAR.into(),
        format: "obj".into(),
        sha256: String::new(),
        data: std::fs::read(bodies.join("regular_1k.obj")).unwrap(),
    }
}

#[test]
fn the_walkthrough_job_is_a_valid_simulate_request_on_the_uploaded_body() {
    let text = walkthrough_job();
    // The shell substitutes only the asset id: no other `$`, no backquotes.
    assert_eq!(text.matches('$').count(), 1, "{text}");
    assert!(text.contains(&format!("\"{ASSET_VAR}\"")), "{text}");
    assert!(!text.contains('`'), "{text}");
    let request: Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}:\n{text}"));
    let keys: Vec<&str> = request
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    assert_eq!(keys, ["kind", "spec"], "POST /v1/jobs takes exactly these");
    assert_eq!(request["kind"], "simulate");
    let spec = &request["spec"];

    let job = SimulateJob;
    let scene = job
        .parse(spec)
        .unwrap_or_else(|e| panic!("spec.{}: {}", e.field, e.message));
    job.validate(&scene)
        .unwrap_or_else(|e| panic!("spec.{}: {}", e.field, e.message));
    assert_eq!(
        job.assets(&scene),
        [AssetRef {
            field: "body.source.path".into(),
            id: ASSET_VAR.into(),
        }]
    );
    // The body the walk-through uploads passes the check made at submission.
    let mut assets = Assets::default();
    assets
        .by_field
        .insert("body.source.path".into(), body_asset());
    job.check_assets(&scene, &assets)
        .unwrap_or_else(|e| panic!("spec.{}: {}", e.field, e.message));

    // It is the scene of examples/calf_sleeve.json, which the command-line tool runs.
    let mut example: Value =
        serde_json::from_str(include_str!("../examples/calf_sleeve.json")).unwrap();
    example["body"]["source"]["path"] = ASSET_VAR.into();
    assert_eq!(spec, &example);
}

#[test]
fn the_walkthrough_uploads_the_body_it_names() {
    let start = README.find("## Service walk-through").expect("the section");
    let section = &README[start..];
    assert!(
        section.contains(
            "--data-binary @../shared/data/bodies/regular_1k.obj -H 'Content-Type: model/obj'"
        ),
        "the upload command changed; keep the test's body in step"
    );
    assert!(section.contains("cargo run --release -- serve"));
}
