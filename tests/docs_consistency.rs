//! What the pages and examples say, checked against themselves and the code (issue 23 item 8:
//! docs/aiding.md described the barometer twice; examples/rig.toml gave the circle's bank as
//! 25°).

use std::path::{Path, PathBuf};

use imu_emu::math::euler_from_quat;
use imu_emu::motion::Motion;
use imu_emu::sim::Simulation;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The Markdown pages: README.md, docs/*.md and the READMEs of protocols/ and templates/.
fn pages() -> Vec<PathBuf> {
    let mut p: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    p.sort();
    for f in [
        "README.md",
        "protocols/README.md",
        "templates/README.md",
        "templates/SOURCES.md",
    ] {
        p.push(root().join(f));
    }
    p
}

/// The prose paragraphs of a page (blank-line separated, code blocks left out), each with
/// its lines joined.
fn paragraphs(text: &str) -> Vec<String> {
    let (mut out, mut cur, mut code) = (Vec::new(), Vec::new(), false);
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            code = !code;
        }
        if code || line.trim_start().starts_with("```") || line.trim().is_empty() {
            if !cur.is_empty() {
                out.push(cur.join(" "));
                cur.clear();
            }
            continue;
        }
        cur.push(line.trim());
    }
    if !cur.is_empty() {
        out.push(cur.join(" "));
    }
    out
}

/// No page says the same thing twice: a paragraph of 200 characters or more appears once.
/// (Shorter ones — a table header, "Tests:" — may repeat.)
#[test]
fn no_page_repeats_a_paragraph() {
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        let mut seen = std::collections::HashSet::new();
        for p in paragraphs(&text).into_iter().filter(|p| p.len() >= 200) {
            let head: String = p.chars().take(80).collect();
            assert!(
                seen.insert(p.clone()),
                "{}: repeated: {head}…",
                page.display()
            );
        }
    }
}

/// examples/rig.toml's comment gives the circle scene's bank angle: the roll of its
/// coordinated turn, atan(v²/(r·g)) = 27.03° at 50 m/s on 500 m.
#[test]
fn rig_example_states_the_circle_bank() {
    let text = std::fs::read_to_string(root().join("examples/rig.toml")).unwrap();
    let line = text
        .lines()
        .find(|l| l.starts_with("scene = \"circle\""))
        .unwrap();
    let stated: f64 = line
        .split("banked ")
        .nth(1)
        .and_then(|r| r.split('°').next())
        .unwrap()
        .parse()
        .unwrap();
    let m = Simulation::builder().scene("circle").build().unwrap();
    let roll = euler_from_quat(m.motion().pose(10.0).q_b_n).0.to_degrees();
    assert!((stated - roll).abs() < 0.005, "{stated}° stated, {roll}°");
}
