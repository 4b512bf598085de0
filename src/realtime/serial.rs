//! Serial-device sink: a UART at a given baud rate and character framing, written
//! non-blocking; before streaming, the link budget is checked (frames × rate × bits per
//! character ≤ baud).

use std::io;
use std::os::fd::{AsRawFd, BorrowedFd};

use super::sink::{FdWriter, Sink, SinkStats, set_nonblocking};

/// Character framing of a UART, like `8N1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Framing {
    /// Data bits (5–8).
    pub data_bits: u8,
    /// Parity: 'N', 'E' or 'O'.
    pub parity: char,
    /// Stop bits (1 or 2).
    pub stop_bits: u8,
}

impl Framing {
    /// Bits on the wire per character: start + data + parity + stop.
    pub fn bits_per_char(self) -> u32 {
        1 + self.data_bits as u32 + u32::from(self.parity != 'N') + self.stop_bits as u32
    }
}

impl std::str::FromStr for Framing {
    type Err = String;
    fn from_str(s: &str) -> Result<Framing, String> {
        let b = s.as_bytes();
        let bad = || format!("framing `{s}`: expected DATA PARITY STOP like 8N1, 8E1, 7O2");
        if b.len() != 3 {
            return Err(bad());
        }
        let data_bits = (b[0] as char).to_digit(10).ok_or_else(bad)? as u8;
        let parity = (b[1] as char).to_ascii_uppercase();
        let stop_bits = (b[2] as char).to_digit(10).ok_or_else(bad)? as u8;
        if !(5..=8).contains(&data_bits) || !"NEO".contains(parity) || !(1..=2).contains(&stop_bits)
        {
            return Err(bad());
        }
        Ok(Framing {
            data_bits,
            parity,
            stop_bits,
        })
    }
}

/// Checks that `frame_bytes` at `rate_hz` fit a `baud` link with `framing`; the error says
/// what is needed.
pub fn check_link(
    frame_bytes: usize,
    rate_hz: f64,
    baud: u32,
    framing: Framing,
) -> Result<(), String> {
    let need = frame_bytes as f64 * rate_hz * framing.bits_per_char() as f64;
    if need > baud as f64 {
        return Err(format!(
            "{frame_bytes}-byte frames at {rate_hz} Hz need {need:.0} bit/s ({} bits per character), more than {baud} baud: raise --baud, lower --rate or use a shorter frame",
            framing.bits_per_char()
        ));
    }
    Ok(())
}

/// A serial device.
pub struct SerialSink {
    label: String,
    port: serialport::TTYPort,
    writer: FdWriter,
}

impl SerialSink {
    /// Opens `dev` at `baud` with `framing`, raw, non-blocking.
    pub fn open(dev: &str, baud: u32, framing: Framing) -> io::Result<SerialSink> {
        use serialport::{DataBits, FlowControl, Parity, StopBits};
        let port = serialport::new(dev, baud)
            .data_bits(match framing.data_bits {
                5 => DataBits::Five,
                6 => DataBits::Six,
                7 => DataBits::Seven,
                _ => DataBits::Eight,
            })
            .parity(match framing.parity {
                'E' => Parity::Even,
                'O' => Parity::Odd,
                _ => Parity::None,
            })
            .stop_bits(if framing.stop_bits == 2 {
                StopBits::Two
            } else {
                StopBits::One
            })
            .flow_control(FlowControl::None)
            .open_native()
            .map_err(|e| io::Error::other(format!("{dev}: {e}")))?;
        // serialport's TTYPort gives only a raw descriptor (no `AsFd`), hence the borrow.
        // SAFETY: the descriptor belongs to `port`, which outlives every use of it here.
        set_nonblocking(unsafe { BorrowedFd::borrow_raw(port.as_raw_fd()) })?;
        Ok(SerialSink {
            label: format!("serial {dev}"),
            port,
            writer: FdWriter::default(),
        })
    }
}

impl Sink for SerialSink {
    fn live(&self) -> bool {
        true
    }

    fn label(&self) -> &str {
        &self.label
    }

    fn write(&mut self, bytes: &[u8], ends: &[usize]) -> io::Result<()> {
        // SAFETY: as in `open`.
        let fd = unsafe { BorrowedFd::borrow_raw(self.port.as_raw_fd()) };
        self.writer.write(fd, bytes, ends)?;
        Ok(())
    }

    fn stats(&self) -> SinkStats {
        self.writer.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 8N1 is 10 bits a character: a 35-byte frame at 2 kHz needs 700 kbit/s.
    #[test]
    fn link_budget() {
        let f: Framing = "8N1".parse().unwrap();
        assert_eq!(f.bits_per_char(), 10);
        assert_eq!("7e2".parse::<Framing>().unwrap().bits_per_char(), 11);
        assert!(check_link(35, 2000.0, 700_000, f).is_ok());
        let e = check_link(35, 2000.0, 460_800, f).unwrap_err();
        assert!(e.contains("700000 bit/s"), "{e}");
        assert!("9N1".parse::<Framing>().is_err());
        assert!("8X1".parse::<Framing>().is_err());
    }
}
