//! Live input as real senders send it (issue 38): a CSV header with a UTF-8 byte-order mark
//! and its columns in another order, CSV states lost on UDP. Real parts: the binary, a
//! pipe, UDP on loopback.

use imu_emu::live::InputFormat;
use imu_emu::live::transport::Receiver;
use imu_emu::run::lockstep::LiveSummary;
use imu_emu::trajectory;

#[path = "common/live_cli.rs"]
mod live_cli;

use live_cli::{circle_lines, join, lockstep_2s, lockstep_pipe, queued_udp};

const BOM: &str = "\u{feff}";

/// `lines` (a comment, the header, the states) with the header and each state's fields in
/// the order `t,lon,lat,h,…`.
fn lon_first(lines: &[String]) -> Vec<String> {
    lines
        .iter()
        .map(|l| {
            if l.starts_with('#') {
                return l.clone();
            }
            let mut f: Vec<&str> = l.split(',').collect();
            f.swap(1, 2);
            f.join(",")
        })
        .collect()
}

/// The library's lockstep run of 2 s at 400 Hz on `datagrams` of CSV text sent over UDP
/// loopback; its output and summary.
fn csv_over_udp(datagrams: &[String]) -> (Vec<u8>, LiveSummary) {
    let mut rx = Receiver::from_socket(queued_udp(datagrams), InputFormat::Csv, "udp");
    lockstep_2s(&mut rx, InputFormat::Csv)
}

/// A CSV stream with a UTF-8 byte-order mark and the header `t,lon,lat,…` (issue 38: the
/// mark made the header a malformed line and the states were read in the default order,
/// latitude and longitude swapped, exit 0). Read as `generate --trajectory` reads a
/// trajectory file: the same samples, and the run writes the bytes of the plain file's —
/// on a pipe, and over UDP with a mark at the start of every datagram (each written as
/// `utf-8-sig`). A header that names a column the trajectory reader does not know fails the
/// run naming it, instead of reading the rows in the default order.
#[test]
fn a_byte_order_mark_and_another_column_order_are_read_as_a_trajectory_file() {
    let lines = circle_lines(3.0);
    let plain = join(&lines);
    // The mark right before the header, as a spreadsheet's export writes it.
    let marked = format!("{BOM}{}", join(&lon_first(&lines[1..])));
    let read = |text: &str| trajectory::parse(text, std::path::Path::new("x.csv")).unwrap();
    assert_eq!(read(&marked), read(&plain), "the trajectory reader");

    let (status, err, want) = lockstep_pipe(&plain, &[]);
    assert!(status.success(), "{err}");
    let (status, err, got) = lockstep_pipe(&marked, &[]);
    assert!(status.success(), "{err}");
    assert!(err.contains(" 0 malformed,"), "{err}");
    assert!(
        got.is_some() && got == want,
        "a pipe: not the plain file's bytes"
    );

    let datagrams: Vec<String> = lon_first(&lines)
        .iter()
        .map(|l| format!("{BOM}{l}"))
        .collect();
    let (got, s) = csv_over_udp(&datagrams);
    assert_eq!(s.stats.malformed, 0, "{:?}", s.stats.problems);
    let mut rx = Receiver::from_stream(
        Box::new(std::io::Cursor::new(plain.into_bytes())),
        InputFormat::Csv,
        "plain",
    );
    let (want, _) = lockstep_2s(&mut rx, InputFormat::Csv);
    assert!(got == want, "UDP: not the plain file's bytes");

    let unknown = marked.replacen("t,lon,lat", "time,lon,lat", 1);
    let (status, err, out) = lockstep_pipe(&unknown, &[]);
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(
        err.contains("stdin: line 1, byte 3: header: column 1: unknown column `time`"),
        "{err}"
    );
    assert!(err.contains("the sender's columns are unknown"), "{err}");
    assert!(out.is_none());
}

/// CSV states lost on UDP (issue 38: the binary datagram's losses were counted from its
/// sequence numbers, CSV's not at all): told from the time steps and counted as missing in
/// gaps, as the binary datagram's are — three single losses, a run of four, and a pair sent
/// in the wrong order (missing when its successor comes, late when it comes).
#[test]
fn lost_csv_states_are_counted_from_the_time_steps() {
    let lines = circle_lines(3.0);
    // lines[2 + k] is the state at k·10 ms.
    let mut sent: Vec<String> = lines[..2].to_vec();
    let mut at = 0;
    for (k, l) in lines[2..].iter().enumerate() {
        if [40, 77, 130].contains(&k) || (100..104).contains(&k) {
            continue;
        }
        if k == 160 {
            at = sent.len();
        }
        sent.push(l.clone());
    }
    sent.swap(at, at + 1);
    let (_, s) = csv_over_udp(&sent);
    let st = &s.stats;
    assert_eq!(
        (st.missing, st.gaps, st.reordered),
        (3 + 4 + 1, 3 + 1 + 1, 1),
        "{st:?}"
    );
    assert!(
        st.summary().contains(" 8 missing in 5 gaps,"),
        "{}",
        st.summary()
    );
}
