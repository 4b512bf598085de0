//! Every shell example in `README.md` and `docs/*.md` runs as written, in document order, on
//! a fresh checkout — the documentation cannot drift from the command line unnoticed.
//!
//! Conventions (also in `docs/testing.md`):
//!
//! * Blocks fenced as `sh`, `bash` or `shell` are scripts; in `console` blocks the lines that
//!   start with `$ ` (and their `\` continuations) are the commands, the rest is output.
//! * Each page is followed on its own, as a reader would from a fresh clone: a new temporary
//!   directory holding copies of `examples/`, `templates/`, `protocols/` and `docs/data/`, the built binary on
//!   `PATH` as `imu-emu`. Its blocks run in order, each as one `bash -eo pipefail` script, so
//!   files made by one block are there for the next.
//! * A block that cannot run here is preceded by `<!-- no-test: REASON -->` (a real device, a
//!   Docker daemon, the test suite itself…); the reason is mandatory.
//! * Long runs are shortened, not skipped: `imu-emu` on `PATH` is a small wrapper that caps every
//!   `--duration` and `--outage` at `IMU_EMU_DOC_SECONDS` simulated seconds (default 2; `compare
//!   --aided` and its outages at half that, so that one outage fits) and gives
//!   `run`, `compare`, `validate` and live `decode` that duration when they have none. The binary
//!   itself reads no such variable; `IMU_EMU_DOC_SECONDS=0` runs every example exactly as
//!   written (the better part of an hour).
//! * `cargo run --release -- ARGS` is the built binary with ARGS, so the test runs it as
//!   `imu-emu ARGS` (running cargo inside `cargo test` would wait on the build lock).
//!
//! A failure names the page and the line of the failing command, with its stderr.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// One runnable block: the page, the Markdown line of its first script line, the script.
#[derive(Debug)]
struct Example {
    first_line: usize,
    script: String,
}

/// Languages whose fenced blocks are whole shell scripts.
const SCRIPT_LANGS: [&str; 3] = ["sh", "bash", "shell"];

/// The runnable blocks of one Markdown page, in order. Errors (a no-test marker without a
/// reason or without a block after it, an unclosed fence) name the line.
fn extract(page: &str, text: &str) -> Result<Vec<Example>, String> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    let mut pending_skip: Option<usize> = None;
    while i < lines.len() {
        let line = lines[i].trim_start();
        if let Some(rest) = line.strip_prefix("<!-- no-test:") {
            let reason = rest.trim_end().trim_end_matches("-->").trim();
            if reason.is_empty() {
                return Err(format!("{page}:{}: no-test marker without a reason", i + 1));
            }
            pending_skip = Some(i + 1);
            i += 1;
            continue;
        }
        let Some(info) = line.strip_prefix("```") else {
            if !line.is_empty()
                && let Some(at) = pending_skip
            {
                return Err(format!(
                    "{page}:{at}: no-test marker not followed by a code block"
                ));
            }
            i += 1;
            continue;
        };
        let lang = info.split_whitespace().next().unwrap_or("");
        let open = i;
        let close = (open + 1..lines.len())
            .find(|&j| lines[j].trim() == "```")
            .ok_or_else(|| format!("{page}:{}: code block never closed", open + 1))?;
        let body = &lines[open + 1..close];
        let skipped = pending_skip.take().is_some();
        if !skipped && (SCRIPT_LANGS.contains(&lang) || lang == "console") {
            let script = if lang == "console" {
                console_commands(body)
            } else {
                body.join("\n")
            };
            out.push(Example {
                first_line: open + 2,
                script: script.replace("cargo run --release -- ", "imu-emu "),
            });
        }
        i = close + 1;
    }
    if let Some(at) = pending_skip {
        return Err(format!(
            "{page}:{at}: no-test marker not followed by a code block"
        ));
    }
    Ok(out)
}

/// The commands of a `console` block: `$ ` lines and their `\` continuations; every other
/// line becomes empty so script line numbers stay those of the page.
fn console_commands(body: &[&str]) -> String {
    let mut continued = false;
    let kept: Vec<&str> = body
        .iter()
        .map(|l| {
            let cmd = if continued {
                Some(*l)
            } else {
                l.strip_prefix("$ ")
            };
            continued = cmd.is_some_and(|c| c.trim_end().ends_with('\\'));
            cmd.unwrap_or("")
        })
        .collect();
    kept.join("\n")
}

/// Simulated seconds every example is capped at; 0 means "as written".
fn cap_seconds() -> String {
    std::env::var("IMU_EMU_DOC_SECONDS").unwrap_or_else(|_| "2".into())
}

/// The `imu-emu` on the examples' PATH: the real binary, with durations capped (see the
/// module comment). Written as a shell script so it applies however a page calls the command.
fn wrapper(real: &Path) -> String {
    format!(
        r#"#!/usr/bin/env bash
# tests/doc_examples.rs: caps simulated time so documentation examples run in seconds.
real='{real}'
cap=${{IMU_EMU_DOC_SECONDS:-2}}
[ "$cap" = 0 ] && exec "$real" "$@"
capped() {{ awk -v d="$1" -v c="${{2:-$cap}}" 'BEGIN {{ if (d + 0 > c + 0) print c; else print d }}'; }}
# compare --aided S: S aided seconds before each outage; both halve so that one fits the cap.
half=$cap; for a in "$@"; do [ "$a" = --aided ] && half=$(awk -v c="$cap" 'BEGIN {{ print c / 2 }}'); done
args=(); prev=; has_duration=0; has_frames=0; live=0
for a in "$@"; do
  case $prev in --duration) a=$(capped "$a") ;; --outage|--aided) a=$(capped "$a" "$half") ;; esac
  case $a in
    --duration) has_duration=1 ;;
    --frames) has_frames=1 ;;
    --serial|--udp-listen) live=1 ;;
  esac
  args+=("$a"); prev=$a
done
case ${{1-}} in
  run|compare|validate) [ $has_duration = 1 ] || args+=(--duration "$cap") ;;
  decode) [ $live = 1 ] && [ $has_duration = 0 ] && [ $has_frames = 0 ] && args+=(--duration "$cap") ;;
esac
exec "$real" "${{args[@]}}"
"#,
        real = real.display()
    )
}

/// A fresh directory as a reader's checkout would offer: the repository's input files (and the
/// data tables the docs read), and a
/// `bin/` with the wrapper.
fn fresh_dir(root: &Path) -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("temporary directory");
    for sub in ["examples", "templates", "protocols", "docs/data"] {
        copy_tree(&root.join(sub), &dir.path().join(sub));
    }
    let bin = dir.path().join(".doc-bin");
    std::fs::create_dir(&bin).unwrap();
    let text = wrapper(Path::new(env!("CARGO_BIN_EXE_imu-emu")));
    install_script(&text, &bin.join("imu-emu"));
    dir
}

/// Writes the executable script `to` with `text` through `install`, not from this process: a
/// child that another test thread forks while this process holds a write descriptor on the
/// file keeps it open until the child execs, and running the file meanwhile fails with
/// ETXTBSY ("Text file busy", seen in CI). The source file written here is never executed.
fn install_script(text: &str, to: &Path) {
    let source = to.with_extension("source");
    std::fs::write(&source, text).unwrap();
    let status = Command::new("install")
        .args(["-m", "755"])
        .arg(&source)
        .arg(to)
        .status()
        .expect("run install");
    assert!(status.success(), "install {}: {status}", to.display());
}

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_tree(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).unwrap();
        }
    }
}

/// Lines the script preamble adds before the page's first line.
const PREAMBLE: &str = "set -eo pipefail\ntrap 'echo \"@@doc-line $LINENO\" >&2' ERR\n";

/// Runs one page's examples in order; the first failure is returned as
/// `page:line: command failed …` with the command's stderr.
fn run_page(page: &str, examples: &[Example], dir: &Path) -> Result<(), String> {
    let path = format!(
        "{}:{}",
        dir.join(".doc-bin").display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let preamble_lines = PREAMBLE.lines().count();
    for ex in examples {
        // The timeout only guards against a hang (a reader waiting on a device that never
        // comes): capped examples take seconds, uncapped ones stream whole scenes in real time.
        let limit = if cap_seconds() == "0" { "7200" } else { "300" };
        let output = Command::new("timeout")
            .args(["--kill-after=5", limit, "bash", "-c"])
            .arg(format!("{PREAMBLE}{}", ex.script))
            .current_dir(dir)
            .env("PATH", &path)
            .env("IMU_EMU_DOC_SECONDS", cap_seconds())
            .output()
            .map_err(|e| format!("{page}:{}: cannot start bash: {e}", ex.first_line))?;
        if output.status.success() {
            continue;
        }
        let stderr = String::from_utf8_lossy(&output.stderr);
        let line = stderr
            .lines()
            .rev()
            .find_map(|l| l.strip_prefix("@@doc-line "))
            .and_then(|n| n.trim().parse::<usize>().ok())
            .map_or(ex.first_line, |n| {
                ex.first_line + n.saturating_sub(preamble_lines + 1)
            });
        let command = ex
            .script
            .lines()
            .nth(line - ex.first_line)
            .unwrap_or("")
            .trim();
        let tail: Vec<&str> = stderr
            .lines()
            .filter(|l| !l.starts_with("@@doc-line"))
            .collect();
        let tail = tail[tail.len().saturating_sub(15)..].join("\n");
        return Err(format!(
            "{page}:{line}: `{command}` failed ({}):\n{tail}",
            output.status
        ));
    }
    Ok(())
}

/// README.md, then docs/*.md in name order.
fn pages(root: &Path) -> Vec<PathBuf> {
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    docs.sort();
    std::iter::once(root.join("README.md"))
        .chain(docs)
        .collect()
}

#[test]
fn every_shell_example_runs() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let started = Instant::now();
    let mut runs = Vec::new();
    for page in pages(root) {
        let label = page.strip_prefix(root).unwrap().display().to_string();
        let text = std::fs::read_to_string(&page).unwrap();
        let examples = extract(&label, &text).unwrap_or_else(|e| panic!("{e}"));
        runs.push((label, examples));
    }
    assert!(
        runs[0].1.len() >= 3,
        "README.md: expected its quickstart blocks, found {}",
        runs[0].1.len()
    );
    // Pages are independent (each in its own directory), so they run side by side.
    let failures: Vec<String> = std::thread::scope(|s| {
        let handles: Vec<_> = runs
            .iter()
            .map(|(page, examples)| {
                s.spawn(move || {
                    let dir = fresh_dir(root);
                    let t = Instant::now();
                    let result = run_page(page, examples, dir.path());
                    eprintln!(
                        "{page}: {} blocks in {:.1} s",
                        examples.len(),
                        t.elapsed().as_secs_f64()
                    );
                    result
                })
            })
            .collect();
        handles
            .into_iter()
            .filter_map(|h| h.join().unwrap().err())
            .collect()
    });
    eprintln!("all pages: {:.1} s", started.elapsed().as_secs_f64());
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// The runner must be able to fail, and say where: a page whose third line fails.
#[test]
fn a_failing_example_is_named_by_page_and_line() {
    let page = "# t\n```sh\ntrue\nls does-not-exist \\\n  -l\necho never\n```\n";
    let examples = extract("t.md", page).unwrap();
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join(".doc-bin")).unwrap();
    let err = run_page("t.md", &examples, dir.path()).unwrap_err();
    assert!(err.starts_with("t.md:4: `ls does-not-exist"), "{err}");
}

#[test]
fn console_blocks_run_only_prompted_lines_and_markers_need_a_reason() {
    let page = "```console\n$ echo a \\\n    b\na b\n$ true\n```\n";
    let ex = extract("c.md", page).unwrap();
    assert_eq!(ex.len(), 1);
    assert_eq!(ex[0].first_line, 2);
    assert_eq!(ex[0].script, "echo a \\\n    b\n\ntrue");

    let skipped = "<!-- no-test: needs a device -->\n```sh\nexit 1\n```\n";
    assert!(extract("s.md", skipped).unwrap().is_empty());
    let bare = "<!-- no-test: -->\n```sh\nexit 1\n```\n";
    assert!(extract("b.md", bare).unwrap_err().contains("b.md:1"));
    let dangling = "<!-- no-test: why -->\ntext\n";
    assert!(extract("d.md", dangling).is_err());
}

/// A run of the wrapper itself: durations above the cap shrink, others stay.
#[test]
fn the_wrapper_caps_durations_only() {
    let dir = tempfile::tempdir().unwrap();
    let echo = dir.path().join("echo-args");
    install_script("#!/bin/sh\necho \"$@\"\n", &echo);
    let wrap = dir.path().join("imu-emu");
    install_script(&wrapper(&echo), &wrap);
    let run = |args: &[&str], cap: &str| {
        let out = Command::new(&wrap)
            .args(args)
            .env("IMU_EMU_DOC_SECONDS", cap)
            .output()
            .unwrap();
        String::from_utf8(out.stdout).unwrap().trim().to_string()
    };
    assert_eq!(
        run(&["generate", "--duration", "600", "-o", "x"], "2"),
        "generate --duration 2 -o x"
    );
    assert_eq!(
        run(&["generate", "--duration", "0.5"], "2"),
        "generate --duration 0.5"
    );
    assert_eq!(run(&["run", "--pty", "p"], "2"), "run --pty p --duration 2");
    assert_eq!(
        run(&["compare", "--outage", "60"], "2"),
        "compare --outage 2 --duration 2"
    );
    assert_eq!(
        run(
            &["compare", "--gnss", "--outage", "10,30", "--aided", "60"],
            "2"
        ),
        "compare --gnss --outage 1 --aided 1 --duration 2"
    );
    assert_eq!(
        run(&["decode", "--protocol", "x", "f.bin"], "2"),
        "decode --protocol x f.bin"
    );
    assert_eq!(
        run(&["decode", "--serial", "p"], "2"),
        "decode --serial p --duration 2"
    );
    assert_eq!(
        run(&["run", "--duration", "600"], "0"),
        "run --duration 600"
    );
}

/// The pages cite only what a reader of this repository has: every relative link resolves to a
/// file here, and no page points at notes kept outside it.
#[test]
fn links_resolve_and_no_page_cites_outside_notes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut bad = Vec::new();
    for page in pages(root) {
        let label = page.strip_prefix(root).unwrap().display().to_string();
        let text = std::fs::read_to_string(&page).unwrap();
        for (n, line) in text.lines().enumerate() {
            for name in [
                "DESIGN.md",
                "DESIGN §",
                "RUST-NOTES",
                "PROTOCOLS.md",
                "HIL.md",
                "shared/",
            ] {
                // The public data sets' default folder (docs/testing.md) is not a note.
                let cited = line.replace("shared/data", "");
                if cited.contains(name) {
                    bad.push(format!("{label}:{}: cites `{name}`", n + 1));
                }
            }
            for target in line.split("](").skip(1).filter_map(|t| t.split(')').next()) {
                let path = target.split('#').next().unwrap_or("");
                if path.is_empty() || path.contains("://") || path.starts_with("mailto:") {
                    continue;
                }
                if !page.parent().unwrap().join(path).exists() {
                    bad.push(format!("{label}:{}: link to missing `{path}`", n + 1));
                }
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}
