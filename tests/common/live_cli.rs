//! Running `imu-emu run --motion tcp://…` from the live test targets (tests/live.rs,
//! tests/live_robust.rs): the child listening on a free loopback port and the connection to
//! it.

use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// Spawns `imu-emu run --motion tcp://127.0.0.1:PORT --time-mode lockstep --file OUT` (stderr
/// piped) on a free port and connects to it once it listens.
pub fn lockstep_over_tcp(out: &Path) -> (Child, TcpStream) {
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let mut child = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .args(["run", "--motion", &format!("tcp://127.0.0.1:{port}")])
        .args(["--time-mode", "lockstep", "--file"])
        .arg(out)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The emulator binds after it starts: try for up to 10 s.
    for _ in 0..400 {
        if let Ok(c) = TcpStream::connect(("127.0.0.1", port)) {
            return (child, c);
        }
        std::thread::sleep(Duration::from_millis(25));
    }
    let _ = child.kill();
    let _ = child.wait();
    panic!("the emulator does not listen on port {port}");
}
