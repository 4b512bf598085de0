//! Where a unit's stream goes, written as one string (a scene file's `sink` key, `--unit-sink`):
//! `pty:PATH`, `serial:DEV`, `udp:HOST:PORT` or `file:PATH` (`KIND://TARGET` also reads).

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
    /// A file, or `-` for stdout.
    File(String),
}

impl SinkAddr {
    /// Reads `KIND:TARGET`; the error says what was expected.
    pub fn parse(s: &str) -> Result<SinkAddr, String> {
        let expected = "expected pty:PATH, serial:DEV, udp:HOST:PORT or file:PATH";
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
            "udp" => match target.rsplit_once(':') {
                Some((h, p)) if !h.is_empty() && p.parse::<u16>().is_ok() => {
                    Ok(SinkAddr::Udp(target.to_string()))
                }
                _ => Err(format!("`{s}`: expected udp:HOST:PORT")),
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
        for bad in ["udp:9001", "udp:host:port", "tcp:x:1", "nothing", "file:"] {
            let e = SinkAddr::parse(bad).unwrap_err();
            assert!(e.contains(bad), "{e}");
        }
        assert_eq!(
            SinkAddr::parse("udp:[::1]:5").unwrap().to_string(),
            "udp:[::1]:5"
        );
    }
}
