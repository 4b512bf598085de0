//! Where a unit's stream goes, written as one string (a scene file's `sink` key, `--unit-sink`):
//! `pty:PATH`, `serial:DEV`, `udp:HOST:PORT`, `tcp:HOST:PORT`, `tcp-listen:ADDR:PORT` or
//! `file:PATH` (`KIND://TARGET` also reads).

use std::fmt;

/// A sink's address, parsed but not opened.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SinkAddr {
    /// A pseudo-terminal whose slave is published at this path (a symlink); `pty:` alone
    /// opens one without a link.
    Pty(Option<String>),
    /// A serial device.
    Serial(String),
    /// A UDP destination `HOST:PORT`.
    Udp(String),
    /// A consumer's TCP port `HOST:PORT`, connected to (and reconnected) by the emulator.
    Tcp(String),
    /// A TCP port `ADDR:PORT` the emulator listens on, sending every frame to every client.
    TcpListen(String),
    /// A file, or `-` for stdout.
    File(String),
}

impl SinkAddr {
    /// Reads `KIND:TARGET[,protocol=NAME]`: the address, and the protocol (built-in name or
    /// spec file) its frames are in when it is not the unit's own.
    pub fn parse_with_protocol(s: &str) -> Result<(SinkAddr, Option<String>), String> {
        let (target, protocol) = match s.rsplit_once(",protocol=") {
            Some((t, p)) => (t, Some(p.to_string())),
            None => (s, None),
        };
        Ok((SinkAddr::parse(target)?, protocol))
    }

    /// Reads `KIND:TARGET`; the error says what was expected.
    pub fn parse(s: &str) -> Result<SinkAddr, String> {
        let expected = "expected pty:PATH, serial:DEV, udp:HOST:PORT, tcp:HOST:PORT, \
                        tcp-listen:ADDR:PORT or file:PATH";
        let Some((kind, target)) = s.split_once(':') else {
            return Err(format!("`{s}`: {expected}"));
        };
        let target = target.strip_prefix("//").unwrap_or(target);
        let need = |what: &str| -> Result<String, String> {
            if target.is_empty() {
                Err(format!("`{s}`: expected {what} after `{kind}:`"))
            } else {
                Ok(target.to_string())
            }
        };
        match kind {
            "pty" => Ok(SinkAddr::Pty(
                (!target.is_empty()).then(|| target.to_string()),
            )),
            "serial" => need("a device").map(SinkAddr::Serial),
            "file" => need("a path").map(SinkAddr::File),
            "udp" | "tcp" | "tcp-listen" => match target.rsplit_once(':') {
                Some((h, p)) if !h.is_empty() && p.parse::<u16>().is_ok() => {
                    let t = target.to_string();
                    Ok(match kind {
                        "udp" => SinkAddr::Udp(t),
                        "tcp" => SinkAddr::Tcp(t),
                        _ => SinkAddr::TcpListen(t),
                    })
                }
                _ => {
                    let host = if kind == "tcp-listen" { "ADDR" } else { "HOST" };
                    Err(format!("`{s}`: expected {kind}:{host}:PORT"))
                }
            },
            _ => Err(format!("`{s}`: unknown sink kind `{kind}`; {expected}")),
        }
    }

    /// True for a file (an unpaced run is possible when every sink is one).
    pub fn is_file(&self) -> bool {
        matches!(self, SinkAddr::File(_))
    }
}

impl fmt::Display for SinkAddr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SinkAddr::Pty(p) => write!(f, "pty:{}", p.as_deref().unwrap_or("")),
            SinkAddr::Serial(d) => write!(f, "serial:{d}"),
            SinkAddr::Udp(d) => write!(f, "udp:{d}"),
            SinkAddr::Tcp(d) => write!(f, "tcp:{d}"),
            SinkAddr::TcpListen(a) => write!(f, "tcp-listen:{a}"),
            SinkAddr::File(p) => write!(f, "file:{p}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every kind reads in both spellings; malformed ones are refused with a reason.
    #[test]
    fn parses_every_kind() {
        let u = SinkAddr::Udp("127.0.0.1:9001".into());
        assert_eq!(SinkAddr::parse("udp:127.0.0.1:9001"), Ok(u.clone()));
        assert_eq!(SinkAddr::parse("udp://127.0.0.1:9001"), Ok(u));
        assert_eq!(
            SinkAddr::parse("pty:/tmp/imu-a"),
            Ok(SinkAddr::Pty(Some("/tmp/imu-a".into())))
        );
        assert_eq!(SinkAddr::parse("pty:"), Ok(SinkAddr::Pty(None)));
        assert_eq!(
            SinkAddr::parse("serial:/dev/ttyUSB0"),
            Ok(SinkAddr::Serial("/dev/ttyUSB0".into()))
        );
        assert!(SinkAddr::parse("file:-").unwrap().is_file());
        assert_eq!(
            SinkAddr::parse("tcp://127.0.0.1:9002"),
            Ok(SinkAddr::Tcp("127.0.0.1:9002".into()))
        );
        assert_eq!(
            SinkAddr::parse("tcp-listen:0.0.0.0:9003"),
            Ok(SinkAddr::TcpListen("0.0.0.0:9003".into()))
        );
        let bad = [
            "udp:9001",
            "udp:host:port",
            "tcp:9002",
            "tcp-listen::9003",
            "tcp-listen:0.0.0.0:x",
            "tcpx:a:1",
            "nothing",
            "file:",
        ];
        for bad in bad {
            let e = SinkAddr::parse(bad).unwrap_err();
            assert!(e.contains(bad), "{e}");
        }
        for s in ["udp:[::1]:5", "tcp:[::1]:6", "tcp-listen:[::]:7"] {
            assert_eq!(SinkAddr::parse(s).unwrap().to_string(), s);
        }
    }
}
