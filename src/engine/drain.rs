//! The offline drivers: a whole run written into a writer, with its side outputs.

use std::io::Write;
use std::ops::ControlFlow;

use crate::errors::ErrorChain;
use crate::output::{self, Format};
use crate::source::AnyMotion;

use super::{BLOCK, Encoding, EngineError, Grid, Producer};

/// Runs the job into `out`, calling `progress(records_done)` after each block.
///
/// With an error `chain`, records are corrupted after generation; `truth`, if given, receives
/// the error-free records in the same format and on the same time grid, and `injected` the
/// error each stage added to each record (`output::components_header`).
#[allow(clippy::too_many_arguments)] // the run's inputs, each distinct; a struct would only rename them
pub fn run(
    motion: AnyMotion,
    grid: Grid,
    nodes: usize,
    encoding: impl Into<Encoding>,
    chain: Option<ErrorChain>,
    out: &mut impl Write,
    truth: Option<&mut dyn Write>,
    injected: Option<&mut dyn Write>,
    mut progress: impl FnMut(u64),
) -> Result<(), EngineError> {
    let producer = Producer::new(motion, grid, nodes, encoding, chain, false)?;
    drain(producer, out, truth, injected, |k| {
        progress(k);
        ControlFlow::Continue(())
    })
}

/// Writes the whole run of a producer that has not started into `out` (and the side
/// outputs, as [`run`] does). After each block `progress(records_done)` may stop the run
/// early with `ControlFlow::Break`, which returns [`EngineError::Stopped`]; a non-finite record
/// stops it with [`EngineError::NonFinite`] before anything of its block is written.
pub fn drain(
    mut producer: Producer,
    out: &mut impl Write,
    mut truth: Option<&mut dyn Write>,
    mut injected: Option<&mut dyn Write>,
    mut progress: impl FnMut(u64) -> ControlFlow<()>,
) -> Result<(), EngineError> {
    let format = producer.side_format();
    if format == Format::Csv {
        if let Some(t) = truth.as_mut() {
            t.write_all(producer.truth_header().as_bytes())?;
        }
        if let Some(t) = injected.as_mut() {
            t.write_all(output::components_header().as_bytes())?;
        }
    }
    if injected.is_some() {
        producer = producer.with_components();
    }
    producer.set_keep_truth(truth.is_some());
    out.write_all(producer.preamble().as_bytes())?;
    let mut buf = Vec::with_capacity(BLOCK * 104);
    let mut side = Vec::new();
    let mut ends = Vec::with_capacity(BLOCK);
    loop {
        buf.clear();
        ends.clear();
        let Some(b) = producer.next_block(BLOCK, &mut buf, &mut ends) else {
            break;
        };
        if let Some(t) = truth.as_mut() {
            side.clear();
            let gnss = b.motion.defined().map(|m| move |t| m.gnss_visible(t));
            let gnss = gnss.as_ref().map(|g| g as &dyn Fn(f64) -> bool);
            output::encode_truth(format, b.truth, b.times.as_ref(), gnss, &mut side);
            t.write_all(&side)?;
        }
        if let Some(w) = injected.as_mut() {
            side.clear();
            output::encode_components(format, b.records, b.components, &mut side);
            w.write_all(&side)?;
        }
        let done = b.first + b.records.len() as u64;
        out.write_all(&buf)?;
        if progress(done).is_break() {
            return Err(EngineError::Stopped);
        }
    }
    if let Some(e) = producer.take_error() {
        return Err(e);
    }
    out.flush()?;
    if let Some(t) = truth.as_mut() {
        t.flush()?;
    }
    if let Some(t) = injected.as_mut() {
        t.flush()?;
    }
    Ok(())
}
