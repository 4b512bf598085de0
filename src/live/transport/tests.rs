//! Endpoints, messages cut from streams and datagrams, stops while waiting.

use super::*;
use crate::live::csv::MAX_LINE_BYTES;
use crate::live::{binary, mavlink};

fn messages(format: InputFormat, bytes: Vec<u8>) -> (Vec<Message>, u64) {
    let mut r = Receiver::from_stream(Box::new(std::io::Cursor::new(bytes)), format, "x");
    let mut out = Vec::new();
    while let Some(m) = r.next_message().unwrap() {
        out.push(m);
    }
    (out, r.skipped_bytes())
}

#[test]
fn parses_endpoints() {
    assert_eq!(
        Endpoint::parse("udp://127.0.0.1:5000").unwrap(),
        Endpoint::Udp("127.0.0.1:5000".parse().unwrap())
    );
    assert_eq!(
        Endpoint::parse("tcp://127.0.0.1:5001").unwrap(),
        Endpoint::Tcp("127.0.0.1:5001".parse().unwrap())
    );
    assert_eq!(
        Endpoint::parse("-").unwrap(),
        Endpoint::Stream(PathBuf::from("-"))
    );
    assert!(
        Endpoint::parse("udp://nohost")
            .unwrap_err()
            .contains("HOST:PORT")
    );
    assert!(
        Endpoint::parse("http://x")
            .unwrap_err()
            .contains("unknown scheme")
    );
}

/// Binary frames are found after garbage and across read boundaries; the garbage and a
/// truncated last frame are counted, each frame named by its byte offset.
#[test]
fn binary_stream_framing() {
    let d = binary::Datagram {
        seq: 1,
        week: binary::NO_WEEK,
        time: 1.0,
        flags: 0,
        pos: [0.0; 3],
        vel: [0.0; 3],
        acc: [0.0; 3],
        quat: [1.0, 0.0, 0.0, 0.0],
        rate: [0.0; 3],
    };
    let f = binary::encode(&d);
    let mut s = b"junk!".to_vec();
    for _ in 0..40 {
        s.extend_from_slice(&f);
    }
    s.extend_from_slice(&f[..60]);
    let (m, skipped) = messages(InputFormat::Binary, s);
    assert_eq!(m.len(), 40);
    assert_eq!(m[0].place, Place::Byte(5));
    assert_eq!(m[39].place, Place::Byte(5 + 39 * 152));
    assert!(m.iter().all(|m| m.bytes == f));
    assert_eq!(skipped, 5 + 60);
}

#[test]
fn csv_and_mavlink_stream_framing() {
    let (m, _) = messages(InputFormat::Csv, b"a,b\r\n\n1,2\n3,4".to_vec());
    let lines: Vec<&[u8]> = m.iter().map(|m| m.bytes.as_slice()).collect();
    assert_eq!(lines, vec![&b"a,b"[..], b"", b"1,2", b"3,4"]);
    assert_eq!(m[3].place, Place::Line(4));
    let f = mavlink::encode(1, 5, [1.0, 0.0, 0.0, 0.0], [0.0; 3], [1, 2, 3], [0; 3]);
    let mut s = vec![0u8, 1, 2];
    s.extend_from_slice(&f);
    s.extend_from_slice(&f);
    let (m, skipped) = messages(InputFormat::Mavlink, s);
    assert_eq!(m.len(), 2);
    assert_eq!(m[1].place, Place::Byte(3 + f.len() as u64));
    assert_eq!(skipped, 3);
}

/// A stream that yields `head`, then `n` bytes of `x` with no line end, then `tail`, a few
/// bytes per read (as a slow sender's TCP segments).
struct LongLine {
    head: Vec<u8>,
    n: usize,
    tail: Vec<u8>,
    at: usize,
}

impl Read for LongLine {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let total = self.head.len() + self.n + self.tail.len();
        let k = buf.len().min(1000).min(total - self.at);
        for b in &mut buf[..k] {
            let i = self.at;
            *b = if i < self.head.len() {
                self.head[i]
            } else if i < self.head.len() + self.n {
                b'x'
            } else {
                self.tail[i - self.head.len() - self.n]
            };
            self.at += 1;
        }
        Ok(k)
    }
}

/// An 8 MB line without a line end (issue 23: once read whole and searched from its start
/// on every read, quadratic in its length) becomes one message of the limit plus one byte,
/// refused by the decoder as too long; the rest is skipped and counted; the buffer never
/// holds more than the limit and a read; the lines after it come out with their numbers,
/// and so does an over-long last line without an end.
#[test]
fn an_overlong_line_is_cut_and_counted() {
    let n = 8 << 20;
    for tail in [&b"\n1,2\n"[..], b""] {
        let stream = LongLine {
            head: b"a,b\n".to_vec(),
            n,
            tail: tail.to_vec(),
            at: 0,
        };
        let mut r = Receiver::from_stream(Box::new(stream), InputFormat::Csv, "x");
        let mut out = Vec::new();
        while let Some(m) = r.next_message().unwrap() {
            assert!(
                r.buf.len() <= MAX_LINE_BYTES + 4096,
                "{} buffered",
                r.buf.len()
            );
            out.push(m);
        }
        let lines: Vec<usize> = out.iter().map(|m| m.bytes.len()).collect();
        let mut want = vec![3, MAX_LINE_BYTES + 1];
        if !tail.is_empty() {
            want.push(3);
        }
        assert_eq!(lines, want);
        assert_eq!(out[1].place, Place::Line(2));
        assert_eq!(out.last().unwrap().place, Place::Line(want.len() as u64));
        // The line's other bytes and its line end.
        let end = usize::from(!tail.is_empty());
        assert_eq!(r.skipped_bytes(), (n - MAX_LINE_BYTES - 1 + end) as u64);
        let e = crate::live::Decoder::new(InputFormat::Csv)
            .decode(&out[1].bytes)
            .unwrap_err();
        assert_eq!(e.offset, MAX_LINE_BYTES);
        assert!(e.message.contains("line longer than 65536 bytes"), "{e:?}");
    }
}
