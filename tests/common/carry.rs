//! The encoder's carried rounding of increments (tests/protocols.rs, tests/protocol_props.rs).

use imu_emu::protocol::Plan;
use imu_emu::protocol::spec::Source;

/// For an increment in an integer field, checks that the frame is within one step of what it
/// was meant to carry and that the running sum of what was sent is within half a step of the
/// running sum meant (the encoder carries each count's remainder into the next frame, as a
/// unit's accumulator does; rounding each frame alone lets the sum drift by up to half a step
/// a frame). `running` keeps the sums per source and the frame last counted (a frame with two
/// fields of one increment, such as LN-200's raw copy, counts once). False for any other
/// field.
pub fn sums_within_half_a_step(
    running: &mut Vec<(Source, usize, f64, f64)>,
    plan: &Plan,
    (s, frame): (Source, usize),
    got: f64,
    want: f64,
) -> bool {
    let increment = match s {
        Source::DTheta(_) | Source::Dv(_) => true,
        Source::Channel(c, _) => c.is_increment(),
        _ => false,
    };
    let Some(q) = plan.quantum(s).filter(|_| increment) else {
        return false;
    };
    let k = match running.iter().position(|x| x.0 == s) {
        Some(k) => k,
        None => {
            running.push((s, usize::MAX, 0.0, 0.0));
            running.len() - 1
        }
    };
    let run = &mut running[k];
    // Float round-off: of the carry (a few ulps of a step) and of the sums.
    let eps = 1e-9 * q + 1e-14 * run.3.abs();
    assert!((got - want).abs() <= q + eps, "{s:?}: {got} vs {want}");
    if run.1 != frame {
        (run.1, run.2, run.3) = (frame, run.2 + got, run.3 + want);
        assert!(
            (run.2 - run.3).abs() <= 0.5 * q + eps,
            "{s:?} frame {frame}: sum sent {} vs {}",
            run.2,
            run.3
        );
    }
    true
}
