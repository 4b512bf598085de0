//! Samples the sensor skipped: no frame goes out for them, and the next sample taken carries
//! their increments, as an integrating sensor's accumulator keeps running while a read-out is
//! missed. The sums of the increments over the run are therefore the same with and without
//! missing samples.

use crate::errors::chain::Components;
use crate::record::Record;

/// Skipped samples not yet carried into a sample taken: their summed item and their number.
pub type Carry<T> = Option<(T, u32)>;

/// Removes the items of `missing` samples from `items` (in place, order kept), folding each
/// run of them into the next item taken with `close(item, sum, count)`; a run at the end
/// waits in `carry` for the next block. Returns the number of items kept.
pub fn merge<T: Copy>(
    items: &mut [T],
    missing: &[bool],
    carry: &mut Carry<T>,
    add: impl Fn(&mut T, &T),
    close: impl Fn(&mut T, &T, u32),
) -> usize {
    let mut w = 0;
    for i in 0..items.len() {
        let item = items[i];
        if missing[i] {
            match carry {
                Some((sum, c)) => {
                    add(sum, &item);
                    *c += 1;
                }
                None => *carry = Some((item, 1)),
            }
            continue;
        }
        let mut kept = item;
        if let Some((sum, c)) = carry.take() {
            close(&mut kept, &sum, c);
        }
        items[w] = kept;
        w += 1;
    }
    w
}

/// [`merge`] for records at `rate_hz`: increments add up, and the rates become the mean over
/// all the intervals the kept record now covers.
pub fn merge_records(
    records: &mut [Record],
    missing: &[bool],
    carry: &mut Carry<Record>,
    rate_hz: f64,
) -> usize {
    merge(
        records,
        missing,
        carry,
        |s, r| {
            s.dtheta += r.dtheta;
            s.dv += r.dv;
            s.flags |= r.flags;
        },
        |r, s, c| {
            r.dtheta += s.dtheta;
            r.dv += s.dv;
            r.flags |= s.flags;
            let per = rate_hz / (c as f64 + 1.0);
            r.gyro = r.dtheta * per;
            r.accel = r.dv * per;
        },
    )
}

/// [`merge`] for the injected errors (rates): the kept record's is the mean over its
/// intervals.
pub fn merge_components(
    comps: &mut [Components],
    missing: &[bool],
    carry: &mut Carry<Components>,
) -> usize {
    let each = |a: &mut Components, b: &Components, f: &dyn Fn(f64) -> f64| {
        for (x, y) in a.0.iter_mut().zip(b.0.iter()) {
            for (u, v) in x.iter_mut().zip(y.iter()) {
                for (p, q) in u.iter_mut().zip(v.iter()) {
                    *p = f(*p + q);
                }
            }
        }
    };
    merge(
        comps,
        missing,
        carry,
        |s, r| each(s, r, &|x| x),
        |r, s, c| each(r, s, &|x| x / (c as f64 + 1.0)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    /// Records 2 and 3 of 5 missing, record 5 missing at the block's end: record 4 carries the
    /// increments of 2–4 and their mean rates; the carry reaches the next block's first
    /// record; the total increment is unchanged.
    #[test]
    fn increments_are_kept() {
        let rec = |k: f64| Record {
            t: k,
            gyro: Vec3::new(k, 0.0, 0.0) * 100.0,
            accel: Vec3::new(0.0, k, 0.0) * 100.0,
            dtheta: Vec3::new(k, 0.0, 0.0),
            dv: Vec3::new(0.0, k, 0.0),
            flags: if k == 2.0 { 1 } else { 0 },
        };
        let mut b: Vec<Record> = (1..=5).map(|k| rec(k as f64)).collect();
        let mut carry = None;
        let n = merge_records(&mut b, &[false, true, true, false, true], &mut carry, 100.0);
        assert_eq!(n, 2);
        assert_eq!(b[1].t, 4.0);
        assert_eq!(b[1].dtheta, Vec3::new(9.0, 0.0, 0.0));
        assert_eq!(b[1].gyro, Vec3::new(300.0, 0.0, 0.0));
        assert_eq!(b[1].accel, Vec3::new(0.0, 300.0, 0.0));
        assert_eq!(b[1].flags, 1);
        let mut next = vec![rec(6.0)];
        assert_eq!(merge_records(&mut next, &[false], &mut carry, 100.0), 1);
        assert_eq!(next[0].dtheta, Vec3::new(11.0, 0.0, 0.0));
        assert_eq!(next[0].gyro, Vec3::new(550.0, 0.0, 0.0));
        assert!(carry.is_none());
        let total = b[0].dtheta + b[1].dtheta + next[0].dtheta;
        assert_eq!(total, Vec3::new(21.0, 0.0, 0.0));
    }
}
