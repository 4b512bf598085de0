//! A child's own peak memory, for tests that memory is bounded by the work and not by the
//! input's size (memory is not timing: a loaded machine does not change it).
// Each test target uses only some of these.
#![allow(dead_code)]

use std::process::{Child, Command, ExitStatus, Stdio};

/// Waits for `child` and returns its status and its own peak resident set size (kB): from
/// `wait4`, which reports the one child waited for, whatever other tests run meanwhile.
pub fn wait_with_rusage(child: Child) -> (ExitStatus, i64) {
    use std::os::unix::process::ExitStatusExt;
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: an all-zero rusage is valid; wait4 fills it and `status` for our own child,
    // which `child` (dropped without waiting) never reaps itself.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let r = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(r, pid, "wait4: {}", std::io::Error::last_os_error());
    (ExitStatus::from_raw(status), usage.ru_maxrss)
}

/// Runs `cmd` (stdout discarded) to its end: its status, stderr and peak memory (kB).
pub fn run_with_peak(cmd: &mut Command) -> (ExitStatus, String, i64) {
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || std::io::read_to_string(stderr).unwrap());
    let (status, peak) = wait_with_rusage(child);
    (status, reader.join().unwrap(), peak)
}
