//! What a stop must not wait for: the output files not yet complete, and the output calls that
//! can block without end (a write into a pipe or FIFO whose reader stopped reading, the open
//! of a FIFO nobody reads). A run stopped by a signal normally ends itself and removes its own
//! files; when its thread is stuck in such a call it never sees the stop, so the command's
//! front end ([`stuck_since`]) removes the files listed here ([`remove_all`]) and exits.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

/// Files written under a name a failed or stopped run must not leave.
static FILES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Output calls under way now, and how many have returned.
static IN_CALL: AtomicUsize = AtomicUsize::new(0);
static RETURNED: AtomicU64 = AtomicU64::new(0);

fn files() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    FILES.lock().unwrap_or_else(|e| e.into_inner())
}

/// Lists `path` as unfinished until [`forget`].
pub fn register(path: &Path) {
    files().push(path.to_path_buf());
}

/// `path` is finished (renamed into place) or already removed.
pub fn forget(path: &Path) {
    let mut f = files();
    if let Some(i) = f.iter().rposition(|p| p == path) {
        f.swap_remove(i);
    }
}

/// Removes every unfinished file (those that are still regular files: never a device or FIFO).
pub fn remove_all() {
    for p in files().drain(..) {
        if std::fs::symlink_metadata(&p).is_ok_and(|m| m.is_file()) {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Runs `call`, an output call that may block without end, counted for [`stuck_since`].
pub fn blocking<T>(call: impl FnOnce() -> T) -> T {
    IN_CALL.fetch_add(1, Ordering::SeqCst);
    let r = call();
    IN_CALL.fetch_sub(1, Ordering::SeqCst);
    RETURNED.fetch_add(1, Ordering::SeqCst);
    r
}

/// A mark of output progress, for [`stuck_since`].
pub fn progress() -> u64 {
    RETURNED.load(Ordering::SeqCst)
}

/// True when an output call is under way and none has returned since `mark` was taken: the
/// writer is blocked, not slow, if that holds long after a stop.
pub fn stuck_since(mark: u64) -> bool {
    IN_CALL.load(Ordering::SeqCst) > 0 && RETURNED.load(Ordering::SeqCst) == mark
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A call under way with none returned is stuck; one returning ends it. Removal spares
    /// what is not a regular file.
    #[test]
    fn a_call_that_does_not_return_is_stuck() {
        let mark = progress();
        let (tx, rx) = std::sync::mpsc::channel::<()>();
        let t = std::thread::spawn(move || blocking(|| rx.recv()));
        while IN_CALL.load(Ordering::SeqCst) == 0 {
            std::thread::yield_now();
        }
        assert!(stuck_since(mark));
        tx.send(()).unwrap();
        t.join().unwrap().unwrap();
        assert!(!stuck_since(mark));

        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        std::fs::write(&a, "x").unwrap();
        std::fs::write(&b, "x").unwrap();
        register(&a);
        register(&b);
        register(dir.path());
        forget(&b);
        remove_all();
        assert!(!a.exists() && b.exists() && dir.path().exists());
    }
}
