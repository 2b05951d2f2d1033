//! Telling instruments apart by what the load cannot change.
//!
//! The straight-line slope of output on input angle over a whole log mixes the ratio with
//! the free travel at the reversals: a deadband twice as wide lowers it, and the deadband
//! narrows as the load takes up slack, so logs of one drive at 10 % and 40 % load differ by
//! 6 % in that slope. Far from a reversal every contact slides and every clearance is
//! taken up, and the output then turns by the transmission ratio per input radian whatever
//! the load: that travel ratio identifies the drive.

use super::model::Prepared;

/// Fraction of a log's input stroke the input must travel past a reversal before the
/// output is taken to follow at the transmission ratio: beyond the widest free travel
/// seen on such drives (about 12 % of the stroke at light load) and the widest contact of
/// the friction memory (20 % of the stroke).
pub const SETTLED_TRAVEL: f64 = 0.3;

/// Output radians per input radian over the travel between reversals, each stroke's
/// first [`SETTLED_TRAVEL`] of the log's stroke left out; `None` when no stroke travels
/// far enough (a log without long strokes cannot say).
pub fn travel_ratio(p: &Prepared) -> Option<f64> {
    let n = p.th_in.len();
    if n < 2 {
        return None;
    }
    let (lo, hi) = p
        .th_in
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let settle = SETTLED_TRAVEL * (hi - lo);
    if settle.is_nan() || settle <= 0.0 {
        return None;
    }
    // Each stroke: from the first sample `settle` past its reversal to its last sample.
    let (mut sxy, mut sxx) = (0.0, 0.0);
    let mut start = 0;
    let mut first: Option<usize> = None;
    for i in 0..=n {
        let ends = i == n || p.dir[i] != p.dir[start];
        if ends {
            if let Some(f) = first {
                let last = i - 1;
                let (di, d_o) = (p.th_in[last] - p.th_in[f], p.th_out[last] - p.th_out[f]);
                sxy += di * d_o;
                sxx += di * di;
            }
            start = i;
            first = None;
            continue;
        }
        if first.is_none() && (p.th_in[i] - p.th_in[start]).abs() >= settle {
            first = Some(i);
        }
    }
    (sxx > 0.0).then(|| sxy / sxx)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::play::play;

    fn log(ratio: f64, play_half_width: f64) -> Prepared {
        let n = 4000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.005).collect();
        let th_in: Vec<f64> = t
            .iter()
            .map(|t| 0.5 + 0.5 * (std::f64::consts::TAU * 0.1 * t).sin())
            .collect();
        let out: Vec<f64> = play(&th_in, play_half_width)
            .iter()
            .map(|p| ratio * p)
            .collect();
        let vel: Vec<f64> = th_in
            .windows(2)
            .map(|w| (w[1] - w[0]) / 0.005)
            .chain(std::iter::once(0.0))
            .collect();
        let mut d = 1.0;
        let dir: Vec<f64> = vel
            .iter()
            .map(|v| {
                if *v != 0.0 {
                    d = v.signum();
                }
                d
            })
            .collect();
        Prepared {
            source: "test".into(),
            straddles_step: vec![false; n],
            travel: vec![0.0; n],
            torque: vec![0.0; n],
            vel_out: vel.clone(),
            vel_in: vel,
            dir,
            th_out: out,
            th_in,
            duration: t[n - 1],
            t,
            q_in: 0.0,
            q_out: 0.0,
        }
    }

    #[test]
    fn the_free_travel_moves_the_slope_but_not_the_travel_ratio() {
        let slope = |p: &Prepared| {
            let n = p.th_in.len() as f64;
            let mi = p.th_in.iter().sum::<f64>() / n;
            let mo = p.th_out.iter().sum::<f64>() / n;
            let sxy: f64 = p
                .th_in
                .iter()
                .zip(&p.th_out)
                .map(|(a, b)| (a - mi) * (b - mo))
                .sum();
            let sxx: f64 = p.th_in.iter().map(|a| (a - mi) * (a - mi)).sum();
            sxy / sxx
        };
        // Free travel 0.12 rad (light load) against 0.06 rad (taken up), ratio 0.9.
        let (wide, narrow) = (log(0.9, 0.12), log(0.9, 0.06));
        let moved = slope(&narrow) / slope(&wide) - 1.0;
        assert!(moved > 0.05, "the whole-log slope moves {moved}");
        for p in [&wide, &narrow] {
            let r = travel_ratio(p).unwrap();
            assert!((r / 0.9 - 1.0).abs() < 1e-9, "{r}");
        }
        let other = travel_ratio(&log(0.81, 0.06)).unwrap();
        assert!((other / 0.81 - 1.0).abs() < 1e-9, "{other}");
    }

    #[test]
    fn a_log_without_long_strokes_says_nothing() {
        let mut p = log(0.9, 0.0);
        p.th_in.iter_mut().for_each(|v| *v = 0.3);
        assert_eq!(travel_ratio(&p), None);
    }
}
