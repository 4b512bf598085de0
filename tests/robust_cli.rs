//! The command line's answers to hostile or unlucky input (issue 23 items 6–8): exit statuses
//! that say what happened and messages that name the place and the cause, never a
//! library's debug output.

use std::path::Path;
use std::process::{Command, Output};

use rand::{RngExt, SeedableRng};

fn imu_emu() -> Command {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `n` random bytes (fixed seed) in `dir/name`.
fn noise_file(dir: &Path, name: &str, n: usize) -> std::path::PathBuf {
    let mut r = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(2323);
    let bytes: Vec<u8> = (0..n).map(|_| r.random::<u8>()).collect();
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// 4 MB of random bytes hold no frame of any built-in protocol: `decode` exits 1 saying so
/// (issue 23 item 6: `ln200`, without a sync word and with a 16-bit sum, found 313 "frames"
/// in 20 MB and exited 0).
#[test]
fn decode_of_noise_finds_no_frame_of_any_protocol() {
    let dir = tempfile::TempDir::new().unwrap();
    let noise = noise_file(dir.path(), "noise.bin", 4 << 20);
    for name in imu_emu::protocol::builtin_names() {
        let o = imu_emu()
            .args(["decode", "--protocol", name, "--tally-only"])
            .arg(&noise)
            .output()
            .unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(err.contains(" 0 frames,"), "{name}: {err}");
        assert!(
            err.contains(&format!("no valid `{name}` frame in the input")),
            "{name}: {err}"
        );
    }
}

/// A spec whose frames have neither a constant field nor a check decodes noise as frames,
/// and `decode` says so.
#[test]
fn decode_warns_when_frames_cannot_be_told_from_noise() {
    let dir = tempfile::TempDir::new().unwrap();
    let spec = dir.path().join("bare.toml");
    std::fs::write(
        &spec,
        "name = \"bare\"\ndescription = \"one word, no sync, no check\"\nrate_hz = 100\n\
         byte_order = \"little\"\n\n[[field]]\nname = \"gyro_x\"\ntype = \"i16\"\n\
         source = \"gyro.x\"\nlsb = 0.001\n",
    )
    .unwrap();
    let noise = noise_file(dir.path(), "noise.bin", 1000);
    let o = imu_emu()
        .arg("decode")
        .arg("--protocol-file")
        .arg(&spec)
        .arg("--tally-only")
        .arg(&noise)
        .output()
        .unwrap();
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("`bare` frames have neither constant fields nor a check"),
        "{err}"
    );
    assert!(err.contains("500 frames"), "{err}");
}

/// `generate`s a CSV record file of `scene` (1 s at 100 Hz) into `dir/name`.
fn records_csv(dir: &Path, scene: &str, name: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    let o = imu_emu()
        .args([
            "generate",
            "--scene",
            scene,
            "--rate",
            "100",
            "--duration",
            "1",
            "-o",
        ])
        .arg(&p)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    p
}

/// A record whose increment no IMU measures (Δθ_x = 1e300 rad) is named with its values
/// (issue 23 item 7: a free-inertial run blamed "the GNSS-aided filter", which it did not
/// use); numbers in `navigate`'s messages are short (a random file's t₀ was printed with
/// 190 digits).
#[test]
fn navigate_names_the_record_not_a_filter_it_did_not_use() {
    let dir = tempfile::TempDir::new().unwrap();
    let rec = records_csv(dir.path(), "circle", "c.csv");
    let text = std::fs::read_to_string(&rec).unwrap();
    let bad: String = text
        .lines()
        .map(|l| match l.strip_prefix("0.5,") {
            Some(rest) => {
                let mut f: Vec<&str> = rest.split(',').collect();
                f[6] = "1e300";
                format!("0.5,{}\n", f.join(","))
            }
            None => format!("{l}\n"),
        })
        .collect();
    std::fs::write(&rec, bad).unwrap();
    let o = imu_emu()
        .arg("navigate")
        .arg(&rec)
        .args(["--scene", "circle"])
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("c.csv: record 50 at t = 0.5 s: increments dtheta [1e300, "),
        "{err}"
    );
    assert!(!err.contains("GNSS"), "{err}");

    let noise = noise_file(dir.path(), "noise.bin", 20_000);
    let o = imu_emu()
        .arg("navigate")
        .arg(&noise)
        .args(["--scene", "circle"])
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(!err.contains("GNSS"), "{err}");
    let longest_number = err
        .split(|c: char| !c.is_ascii_digit())
        .map(str::len)
        .max()
        .unwrap_or(0);
    assert!(longest_number <= 17, "{err}");
}

/// A plot that cannot be written names the file and the system's reason (issue 23 item 7:
/// `ImageError(IoError(Os { code: 2, … }))`), for PNG and SVG alike, and leaves no file.
#[test]
fn analyze_plot_that_cannot_be_written_says_why() {
    let dir = tempfile::TempDir::new().unwrap();
    let rec = records_csv(dir.path(), "static", "s.csv");
    // A disk that fills up while the plot is written.
    std::os::unix::fs::symlink("/dev/full", dir.path().join("full.png")).unwrap();
    let d = dir.path().display();
    for (plot, why) in [
        (
            format!("{d}/none/adev.png"),
            "none/adev.png: cannot write the plot: No such file or directory",
        ),
        (
            format!("{d}/s.csv/adev.svg"),
            "adev.svg: cannot write the plot: Not a directory",
        ),
        (
            format!("{d}/full.png"),
            "full.png: cannot write the plot: No space left on device",
        ),
    ] {
        let o = imu_emu()
            .arg("analyze")
            .arg(&rec)
            .args(["--plot", &plot])
            .output()
            .unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(why), "{err}");
        assert!(!err.contains("Os {") && !err.contains("Error("), "{err}");
    }
    assert!(!dir.path().join("none").exists());
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(left.len(), 2, "only the records and the link: {left:?}");
}
