//! The `bring_your_own` example (its own device and pipeline, skinlet's culling passes in its
//! encoder) runs and reports an image equal to its unculled draw, with meshlets culled. `cargo
//! test` builds the example before it runs the tests.

mod common;

#[test]
fn bring_your_own_draws_what_the_unculled_crowd_draws() {
    let Some(_) = common::gpu() else { return };
    let exe = std::env::current_exe().unwrap();
    let example = exe.parent().and_then(|deps| deps.parent()).unwrap().join("examples/bring_your_own");
    assert!(
        example.exists(),
        "{} is missing: build it with `cargo build -p skinlet-gpu --examples`",
        example.display()
    );
    let out = std::process::Command::new(&example).arg("--json").output().unwrap();
    let line = String::from_utf8_lossy(&out.stdout);
    eprintln!("{line}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the example failed: {line}");
    assert_eq!(line.lines().count(), 1, "--json prints one line");
    let field = |name: &str| -> f64 {
        let at = line.find(&format!("\"{name}\": ")).unwrap_or_else(|| panic!("no {name} in {line}"));
        let rest = &line[at + name.len() + 4..];
        rest[..rest.find([',', '}']).unwrap()].trim().parse().unwrap()
    };
    assert!(line.contains("\"equal_to_unculled\": true"), "{line}");
    assert_eq!(field("differing_pixels"), 0.0);
    assert!(field("covered_pixels") > 1000.0, "the crowd must cover the image: {line}");
    assert!(field("culled_pct") > 5.0, "the crowd must have meshlets to cull: {line}");
}
