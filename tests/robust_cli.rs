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
