//! Design answers drawn from sweep results.

/// Preload above which backlash flattens: the smallest preload at which the backlash is
/// within `tolerance` (e.g. 0.2 = 20 %) of its infinite-preload limit `asymptote`,
/// interpolated linearly between the swept preloads. `None` when no swept preload gets
/// there. `points` are `(preload N, backlash)` in any order; non-finite backlash (slack or
/// gross slip cases) is ignored.
pub fn flattening_preload(points: &[(f64, f64)], asymptote: f64, tolerance: f64) -> Option<f64> {
    let mut pts: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let limit = asymptote * (1.0 + tolerance);
    let first = pts.iter().position(|p| p.1 <= limit)?;
    if first == 0 {
        return Some(pts[0].0);
    }
    let (p0, b0) = pts[first - 1];
    let (p1, b1) = pts[first];
    if b0 == b1 {
        return Some(p1);
    }
    Some(p0 + (p1 - p0) * (b0 - limit) / (b0 - b1))
}

/// Finest tolerance a bisection resolves, relative to the larger magnitude of its range's
/// ends: finer asks for digits a double cannot hold between the bracket's ends.
pub const BISECTION_TOLERANCE_FLOOR_REL: f64 = 1e-9;

/// Most probes of one bisection. With the tolerance floor a search needs at most about
/// `log2(1e9) + 2 = 32` probes on a range that starts at zero, and only ranges spanning
/// many decades need more; the limit is a guard, and a search that meets it says so.
pub const MAX_BISECTION_PROBES: usize = 200;

/// Outcome of a bisection.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Bisection {
    /// The value found (see the search); `None` when the end that must pass fails.
    pub value: Option<f64>,
    /// Tolerance the search worked to: the one asked for, or the floor when that was finer.
    pub tolerance: f64,
    /// Whether the asked tolerance was raised to the floor.
    pub tolerance_raised: bool,
    /// Probes made (calls of the predicate).
    pub probes: usize,
    /// Whether the search stopped on [`MAX_BISECTION_PROBES`] before its tolerance: the
    /// value then passes, but the bracket is wider than the tolerance.
    pub stopped_on_limit: bool,
}

impl Bisection {
    /// What a report should add to the value: a raised tolerance, a search stopped on its
    /// limit; `None` when neither happened.
    pub fn note(&self, asked: f64) -> Option<String> {
        let mut notes = Vec::new();
        if self.tolerance_raised {
            notes.push(format!(
                "tolerance {} raised to {} (a search resolves at most {} of its range's magnitude)",
                crate::compact(asked),
                crate::compact(self.tolerance),
                crate::number(BISECTION_TOLERANCE_FLOOR_REL)
            ));
        }
        if self.stopped_on_limit {
            notes.push(format!(
                "the search stopped on its limit of {MAX_BISECTION_PROBES} probes before reaching its tolerance; narrow the range"
            ));
        }
        (!notes.is_empty()).then(|| notes.join("; "))
    }
}

/// The bisection behind [`least_passing`] and [`largest_passing`]: the end that must pass
/// is `hi` when `passing_end_is_hi`, else `lo`; floor and probe limit applied.
fn bisect(
    lo: f64,
    hi: f64,
    tol: f64,
    passing_end_is_hi: bool,
    meets: impl Fn(f64) -> bool,
) -> Bisection {
    let floor = (BISECTION_TOLERANCE_FLOOR_REL * lo.abs().max(hi.abs())).max(f64::MIN_POSITIVE);
    let tolerance = if tol.is_finite() && tol >= floor {
        tol
    } else {
        floor
    };
    let probes = std::cell::Cell::new(0usize);
    let probe = |x: f64| {
        probes.set(probes.get() + 1);
        meets(x)
    };
    let (must_pass, may_pass) = if passing_end_is_hi {
        (hi, lo)
    } else {
        (lo, hi)
    };
    let mut stopped_on_limit = false;
    let value = if !probe(must_pass) {
        None
    } else if probe(may_pass) {
        Some(may_pass)
    } else {
        let (mut pass, mut fail) = (must_pass, may_pass);
        while (pass - fail).abs() > tolerance {
            if probes.get() >= MAX_BISECTION_PROBES {
                stopped_on_limit = true;
                break;
            }
            let m = 0.5 * (pass + fail);
            // Adjacent doubles: nothing lies between them to probe.
            if m == pass || m == fail {
                break;
            }
            if probe(m) {
                pass = m;
            } else {
                fail = m;
            }
        }
        Some(pass)
    };
    Bisection {
        value,
        tolerance,
        tolerance_raised: tolerance != tol,
        probes: probes.get(),
        stopped_on_limit,
    }
}

/// Smallest `x` in `[lo, hi]` for which `meets(x)` holds, to within `tol` (same unit as
/// `x`; raised to the floor when finer), for a predicate that fails below some threshold
/// and holds above it. The value passes (the upper end of the final bracket); `None` when
/// `hi` fails. `meets` is called about `log2((hi - lo) / tol) + 2` times.
pub fn least_passing(lo: f64, hi: f64, tol: f64, meets: impl Fn(f64) -> bool) -> Bisection {
    bisect(lo, hi, tol, true, meets)
}

/// Largest `x` in `[lo, hi]` for which `meets(x)` holds, to within `tol` (same unit as
/// `x`; raised to the floor when finer), for a predicate that holds below some threshold
/// and fails above it: the largest load, or the fastest scan, that still meets the
/// pointing target. The value passes (the lower end of the final bracket); `None` when
/// `lo` fails.
pub fn largest_passing(lo: f64, hi: f64, tol: f64, meets: impl Fn(f64) -> bool) -> Bisection {
    bisect(lo, hi, tol, false, meets)
}

/// Definition printed with [`least_preload_at_load`].
pub const LEAST_PRELOAD_DEFINITION: &str = "least preload at which the +M, -M, +M backlash \
protocol at the given load completes with both spans taut (no slack) and no gross slip of \
the cable on pulley or drum; found by bisection, assuming a higher preload never fails where \
a lower one passes";

/// Least preload avoiding slack and gross slip at a load.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LeastPreload {
    /// Transmitted torque `M` of the protocol, N m.
    pub load_nm: f64,
    /// The answer, N: passes, and `tolerance_n` less does not (`None`: even the upper end
    /// of the search fails).
    pub preload_n: Option<f64>,
    /// Bisection tolerance worked to, N (the one asked for, or the floor when finer).
    pub tolerance_n: f64,
    /// Probes made (backlash protocols run).
    pub probes: usize,
    /// A raised tolerance or a search stopped on its limit, in words; `None` otherwise.
    pub note: Option<String>,
    /// Searched range, N.
    pub range_n: (f64, f64),
    /// `M / (2 r_drum)`, N, for comparison: the slack limit if the span tensions moved by
    /// equal and opposite amounts. The wraps' friction makes them move unequally, so the
    /// answer may lie a little below it.
    pub slack_bound_n: f64,
    /// What the answer means.
    pub definition: &'static str,
}

/// Least preload (N) at which the backlash protocol at `load_nm` (N m) runs in the `ok`
/// regime, searched in `[lo_n, hi_n]` to within `tol_n` (N). Other drive parameters are
/// those of `drive`.
pub fn least_preload_at_load(
    drive: &crate::physics::DriveParams,
    load_nm: f64,
    model: crate::physics::HysteresisModel,
    (lo_n, hi_n): (f64, f64),
    tol_n: f64,
) -> LeastPreload {
    use crate::study::quasi_static::{backlash, Regime};
    // Preloads beyond the strain the model accepts are not candidates, not failures.
    let hi_n = hi_n.min(crate::physics::drive::MAX_PRELOAD_STRAIN * drive.cable_modulus_n);
    let params = crate::study::quasi_static::BacklashParams { load_nm, model };
    let ok = |p: f64| {
        let d = crate::physics::DriveParams {
            preload_n: p,
            ..drive.clone()
        };
        d.validate().is_ok() && backlash(&d, &params).regime == Regime::Ok
    };
    let search = least_passing(lo_n, hi_n, tol_n, ok);
    LeastPreload {
        load_nm,
        preload_n: search.value,
        tolerance_n: search.tolerance,
        probes: search.probes,
        note: search.note(tol_n),
        range_n: (lo_n, hi_n),
        slack_bound_n: load_nm / (2.0 * drive.drum_radius_m),
        definition: LEAST_PRELOAD_DEFINITION,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flattening_interpolates() {
        let pts = [(10.0, 3.0), (20.0, 1.5), (40.0, 1.1)];
        // limit 1.2 lies between 1.5 and 1.1 at three quarters of the way to 40.
        let p = flattening_preload(&pts, 1.0, 0.2).unwrap();
        assert!((p - 35.0).abs() < 1e-12);
        assert_eq!(flattening_preload(&pts, 0.5, 0.2), None);
    }

    #[test]
    fn least_preload_bisects() {
        let p = least_passing(1.0, 500.0, 1e-6, |x| x >= 37.25)
            .value
            .unwrap();
        assert!((p - 37.25).abs() < 1e-5);
        assert_eq!(least_passing(1.0, 2.0, 1e-3, |_| false).value, None);
    }

    #[test]
    fn passing_bounds_bracket_the_threshold() {
        let x = largest_passing(0.0, 10.0, 1e-8, |v| v <= 2.5)
            .value
            .unwrap();
        assert!(x <= 2.5 && 2.5 - x < 1e-8, "{x}");
        assert_eq!(largest_passing(0.0, 10.0, 1e-3, |_| true).value, Some(10.0));
        assert_eq!(largest_passing(0.0, 10.0, 1e-3, |_| false).value, None);
        let x = least_passing(0.0, 10.0, 1e-8, |v| v >= 7.0).value.unwrap();
        assert!(x >= 7.0 && x - 7.0 < 1e-8, "{x}");
        assert_eq!(least_passing(0.0, 10.0, 1e-3, |_| true).value, Some(0.0));
    }

    /// Tolerances finer than a double resolves, or none at all, and ranges over hundreds
    /// of decades: every search ends, within its probe limit, and says what it did.
    #[test]
    fn absurd_tolerances_and_ranges_end_and_say_so() {
        for tol in [1e-300, 0.0, -1.0, f64::NAN, f64::MIN_POSITIVE] {
            let b = least_passing(1.0, 500.0, tol, |x| x >= 37.25);
            let x = b.value.unwrap();
            assert!(
                x >= 37.25 && x - 37.25 <= 500.0 * BISECTION_TOLERANCE_FLOOR_REL,
                "{x}"
            );
            assert!(
                b.tolerance_raised && b.probes <= MAX_BISECTION_PROBES,
                "{b:?}"
            );
            assert!(
                b.note(tol).unwrap().contains("raised to"),
                "{:?}",
                b.note(tol)
            );
        }
        let b = largest_passing(1e-300, 1e300, 1e-6, |x| x <= 3.0);
        assert!(
            b.value.unwrap() <= 3.0 && b.probes <= MAX_BISECTION_PROBES,
            "{b:?}"
        );
        let fine = least_passing(0.0, 10.0, 1e-3, |v| v >= 7.0);
        assert_eq!(fine.note(1e-3), None);
        assert!(!fine.stopped_on_limit && fine.probes < 20);
        // A range whose bracket cannot shrink to the tolerance within the limit.
        let wide = least_passing(-1e300, 1e300, 1e-6, |x| x >= 1.0);
        assert!(wide.value.unwrap() >= 1.0 && wide.probes <= MAX_BISECTION_PROBES + 2);
    }

    #[test]
    fn least_preload_at_load_clears_the_slack_bound() {
        let drive = crate::physics::DriveParams::default();
        let r = least_preload_at_load(
            &drive,
            0.72,
            crate::physics::HysteresisModel::Memory,
            (0.01, 1000.0),
            0.01,
        );
        let p = r.preload_n.unwrap();
        assert!(
            (0.5..1.5).contains(&(p / r.slack_bound_n)),
            "{p} vs {}",
            r.slack_bound_n
        );
        let regime = |preload_n: f64| {
            crate::study::quasi_static::backlash(
                &crate::physics::DriveParams {
                    preload_n,
                    ..drive.clone()
                },
                &crate::study::quasi_static::BacklashParams {
                    load_nm: 0.72,
                    model: crate::physics::HysteresisModel::Memory,
                },
            )
            .regime
        };
        assert_eq!(regime(p), crate::study::quasi_static::Regime::Ok);
        assert_ne!(regime(p - 0.02), crate::study::quasi_static::Regime::Ok);
        for above in [1.01, 1.5, 3.0, 30.0] {
            assert_eq!(regime(p * above), crate::study::quasi_static::Regime::Ok);
        }
    }
}
