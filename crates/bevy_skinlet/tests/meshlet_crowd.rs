//! The `meshlet_crowd` example on a small crowd (headless, lavapipe on CPU-only machines),
//! with a wall and occlusion culling (Bevy's, skinlet's starting from its depth): its JSON has skinlet's counts read back from the GPU, both
//! pipelines' timings, and frames where skinlet's image matches Bevy's (the tolerance of
//! `tests/meshlet_draw.rs`) and its culled image equals its unculled one.

#[path = "../examples/meshlet_crowd.rs"]
mod meshlet_crowd;

#[test]
fn the_crowd_example_reports_and_matches_bevy() {
    let args = meshlet_crowd::Args {
        per_character: 3,
        frames: 4,
        block: 2,
        compare: 2,
        width: 256,
        height: 160,
        occlusion_rounds: 4,
        bevy_occlusion: true,
        pipeline: meshlet_crowd::Pipelines::Both,
        pictures: Some(std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"))),
        json: true,
    };
    let Some(out) = meshlet_crowd::run(&args) else { return };
    eprintln!("{}", serde_json::to_string_pretty(&out).unwrap());
    assert_eq!(out["instances"], 12);
    assert_eq!(out["equal_to_unculled"], true);
    // Two draws per bake in Bevy's opaque pass with occlusion culling.
    assert_eq!(out["draws_issued"], 8);
    for side in ["bevy", "skinlet"] {
        assert_eq!(out["cpu"][side]["frames"], 4, "{side}");
        assert!(out["cpu"][side]["update_ms_per_frame"].as_f64().unwrap() > 0.0, "{side}");
    }
    let moving = &out["skinlet_per_moving_frame"];
    assert!(moving["frames_read_back"].as_u64().unwrap() >= 1);
    let (total, drawn) = (out["meshlets_total"].as_u64().unwrap(), out["meshlets_drawn"].as_f64().unwrap());
    assert!(0.0 < drawn && drawn < total as f64, "{drawn} of {total} meshlets drawn");
    let compared = out["compared"].as_array().unwrap();
    assert_eq!(compared.len(), 2);
    for c in compared {
        let (drawn, over) = (c["drawn_by_bevy"].as_u64().unwrap(), c["pixels_over_2_levels"].as_u64().unwrap());
        assert!(drawn > 0 && over * 200 <= drawn, "{c}");
        assert!(c["meshlets_drawn"].as_u64().unwrap() <= c["meshlets_tested_visible"].as_u64().unwrap(), "{c}");
        assert_eq!(c["bevy_occluders"], true, "{c}");
        assert!(c["triangles_drawn"].as_u64().unwrap() < c["triangles_total"].as_u64().unwrap(), "{c}");
    }
}
