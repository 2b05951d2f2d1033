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

/// Smallest `x` in `[lo, hi]` for which `meets(x)` holds, to within `tol` (same unit as
/// `x`), for a predicate that fails below some threshold and holds above it. Returns a
/// value that passes (the upper end of the final bracket), or `None` when `hi` fails.
/// `meets` is called about `log2((hi - lo) / tol) + 2` times.
pub fn least_passing(lo: f64, hi: f64, tol: f64, meets: impl Fn(f64) -> bool) -> Option<f64> {
    if !meets(hi) {
        return None;
    }
    if meets(lo) {
        return Some(lo);
    }
    let (mut fail, mut pass) = (lo, hi);
    while pass - fail > tol {
        let m = 0.5 * (fail + pass);
        if meets(m) {
            pass = m;
        } else {
            fail = m;
        }
    }
    Some(pass)
}

/// Largest `x` in `[lo, hi]` for which `meets(x)` holds, to within `tol` (same unit as
/// `x`), for a predicate that holds below some threshold and fails above it: the largest
/// load, or the fastest scan, that still meets the pointing target. Returns a value that
/// passes (the lower end of the final bracket), or `None` when `lo` fails.
pub fn largest_passing(lo: f64, hi: f64, tol: f64, meets: impl Fn(f64) -> bool) -> Option<f64> {
    if !meets(lo) {
        return None;
    }
    if meets(hi) {
        return Some(hi);
    }
    let (mut pass, mut fail) = (lo, hi);
    while fail - pass > tol {
        let m = 0.5 * (pass + fail);
        if meets(m) {
            pass = m;
        } else {
            fail = m;
        }
    }
    Some(pass)
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
    /// Bisection tolerance, N.
    pub tolerance_n: f64,
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
    LeastPreload {
        load_nm,
        preload_n: least_passing(lo_n, hi_n, tol_n, ok),
        tolerance_n: tol_n,
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
        let p = least_passing(1.0, 500.0, 1e-6, |x| x >= 37.25).unwrap();
        assert!((p - 37.25).abs() < 1e-5);
        assert_eq!(least_passing(1.0, 2.0, 1e-3, |_| false), None);
    }

    #[test]
    fn passing_bounds_bracket_the_threshold() {
        let x = largest_passing(0.0, 10.0, 1e-9, |v| v <= 2.5).unwrap();
        assert!(x <= 2.5 && 2.5 - x < 1e-9, "{x}");
        assert_eq!(largest_passing(0.0, 10.0, 1e-3, |_| true), Some(10.0));
        assert_eq!(largest_passing(0.0, 10.0, 1e-3, |_| false), None);
        let x = least_passing(0.0, 10.0, 1e-9, |v| v >= 7.0).unwrap();
        assert!(x >= 7.0 && x - 7.0 < 1e-9, "{x}");
        assert_eq!(least_passing(0.0, 10.0, 1e-3, |_| true), Some(0.0));
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
