//! Closed form of a preloaded figure-eight capstan drive loaded once from rest (virgin
//! cable, quasi-static), independent of the crate's solver: the torque at which the loose
//! half's slip zone reaches the pulley's neutral point (gross slip).
//!
//! A half with span tension `T` and preload `P` stretches (times the modulus `EA`) by
//! `L (T - P)` along its free span of length `L`, plus on each wrap of radius `R` and length
//! `Phi` the stretch of its slip zone, where the tension runs exponentially from `T` to `P`
//! over `s = |ln(T/P)| / mu`, cut at `Phi`:
//! `R (T (1 - exp(-mu s)) / mu - P s)` for `T > P`, `R (T (exp(mu s) - 1) / mu - P s)` for
//! `T < P`. The two halves take up the motion in equal and opposite stretches, so the tight
//! tension follows from the loose one by `e(T_tight) = -e(T_loose)`; the drum carries
//! `M = r_drum (T_tight - T_loose)`. The pulley wrap of a half reaches the neutral point at
//! half the total pulley wrap: gross slip when `T_loose = P exp(-mu pulley_wrap / 2)`.
//! Everything is homogeneous in the tensions: the torque is proportional to the preload.

/// Geometry and friction of the drive (metres, radians).
pub struct Drive {
    pub pulley_radius_m: f64,
    pub drum_radius_m: f64,
    pub center_distance_m: f64,
    pub friction_coefficient: f64,
    pub drum_wrap_rad: f64,
    pub pulley_wrap_rad: f64,
}

/// The shipped drive (`DriveParams::default()`, paper_fig11's [drive]).
pub const PAPER_DRIVE: Drive = Drive {
    pulley_radius_m: 0.020,
    drum_radius_m: 0.1025,
    center_distance_m: 0.1450595,
    friction_coefficient: 0.2,
    drum_wrap_rad: std::f64::consts::PI,
    pulley_wrap_rad: 6.0 * std::f64::consts::PI,
};

fn wrap_stretch(d: &Drive, t: f64, p: f64, wrap_rad: f64, radius_m: f64) -> f64 {
    let mu = d.friction_coefficient;
    let s = ((t / p).ln().abs() / mu).min(wrap_rad);
    if t >= p {
        radius_m * (t * (1.0 - (-mu * s).exp()) / mu - p * s)
    } else {
        radius_m * (t * ((mu * s).exp() - 1.0) / mu - p * s)
    }
}

/// Stretch of a half times `EA`, m N.
fn stretch(d: &Drive, t: f64, p: f64) -> f64 {
    let span = (d.center_distance_m.powi(2) - (d.drum_radius_m + d.pulley_radius_m).powi(2)).sqrt();
    span * (t - p)
        + wrap_stretch(d, t, p, d.drum_wrap_rad, d.drum_radius_m)
        + wrap_stretch(d, t, p, d.pulley_wrap_rad / 2.0, d.pulley_radius_m)
}

/// Drum torque (N m) at which a drive of preload `preload_n` loaded from rest slips
/// grossly on the pulley, with the tight and loose span tensions (N) then.
pub fn gross_slip_torque_nm(d: &Drive, preload_n: f64) -> (f64, f64, f64) {
    let loose = preload_n * (-d.friction_coefficient * d.pulley_wrap_rad / 2.0).exp();
    let target = -stretch(d, loose, preload_n);
    // The stretch grows with the tension: bisect for the tight tension.
    let (mut lo, mut hi) = (preload_n, 1e3 * preload_n);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if stretch(d, mid, preload_n) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (d.drum_radius_m * (lo - loose), lo, loose)
}
