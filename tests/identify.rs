//! Diagnosis against bench logs with hidden effects of known size, made by an independent
//! truth (`tests/support/truth.rs`: a grid cable, an instrument a little off the scenario,
//! coloured noise and outliers), so that a diagnosis which only recognises its own model's
//! output fails here.

mod support;

use cable_servo::identify::{diagnose, effect_value, BenchLog, DiagnoseOptions, EffectName};
use cable_servo::io::benchlog::{read_bench_log, write_bench_log};
use cable_servo::scenario::Scenario;
use support::rates::{
    claimed_rates, clean_rate, opts, opts_every, opts_library, run_effect, scenario, size_range,
    size_tolerance, truth,
};
use support::truth::{oracle_jump_mrad, truth_log, Instrument, Ringing, TruthOptions};

/// The truth's cable against the oracle table of physics.md section 6 (reversal jump, mrad,
/// by load and preload), anchor-cut cells and the slack side included. The grid's
/// trapezoid sum is second order in the node spacing: at 600 nodes per region (5.2 mrad of
/// drum wrap) the kinks of the profile cost a few 1e-5 of the jump (4.7e-5 at worst), so
/// 1e-4 holds. The jump is negative: back at `+M` the output lags.
#[test]
fn truth_cable_reproduces_the_oracle_reversal_jumps() {
    let cells = [
        (0.72, 100.0, 0.432968),
        (1.3, 100.0, 0.858402),
        (0.15, 10.0, 0.102098),
        (1.0, 10.0, 1.53743),
        (0.47, 50.0, 0.293141),
        (3.0, 20.0, 6.01402),
        (1.3, 180.0, 0.782041),
    ];
    for (m, p, want) in cells {
        let got = oracle_jump_mrad(m, p, 600).unwrap_or_else(|e| panic!("{m} N m, {p} N: {e}"));
        assert!(
            (-got / want - 1.0).abs() < 1e-4,
            "{m} N m, {p} N: {got} mrad, oracle {want}"
        );
    }
    let slack = oracle_jump_mrad(3.0, 10.0, 600);
    assert!(
        slack.as_ref().is_err_and(|e| e.contains("slack")),
        "{slack:?}"
    );
}

/// Seeds per effect: 12 for the library, 6 for the multi-wrap effects (each diagnosis
/// searches all eleven), the first draws of `cargo bench --bench identify_rates`, which
/// runs 50.
const SEEDS: u64 = 12;
const SEEDS_EXTENDED: u64 = 6;

/// Named and sized right in at least the share of the draws `docs/diagnose.md` states
/// ([`claimed_rates`]); the suite's draws are the first of the 50 measured there.
fn check_effect(e: EffectName) {
    let seeds = if EffectName::EXTENDED.contains(&e) {
        SEEDS_EXTENDED
    } else {
        SEEDS
    };
    let r = run_effect(e, seeds);
    let (named, sized) = claimed_rates(e);
    let need = |rate: f64| (rate * seeds as f64).ceil() as usize;
    assert!(
        r.named >= need(named) && r.sized >= need(sized),
        "{e}: named {}/{seeds}, sized {}/{seeds} (worst {:.1} %)",
        r.named,
        r.sized,
        r.worst * 100.0
    );
}

macro_rules! effect_tests {
    ($($name:ident => $e:expr;)*) => {$(
        #[test]
        fn $name() {
            check_effect($e);
        }
    )*};
}

effect_tests! {
    finds_input_pulley_runout => EffectName::InputPulleyRunout;
    finds_output_drum_runout => EffectName::OutputDrumRunout;
    finds_encoder_delay => EffectName::EncoderDelay;
    finds_encoder_scale_error => EffectName::EncoderScaleError;
    finds_preload_relaxation => EffectName::PreloadRelaxation;
    finds_bearing_friction => EffectName::BearingFriction;
    finds_cable_transport => EffectName::CableTransport;
    finds_thermal_drift => EffectName::ThermalDrift;
    finds_angle_dependent_ratio => EffectName::AngleDependentRatio;
    finds_load_compliance => EffectName::LoadCompliance;
    finds_distributed_friction_memory => EffectName::DistributedFrictionMemory;
}

/// Draws `0..draws` of the signed effect `e`, the signs alternating (negative on even
/// seeds), half of them within a factor 2 of the smallest size: each one named must be
/// sized within the effect's tolerance and its report must say which way it went
/// (`words.0` for a negative size, `words.1` for a positive one); `on_miss` judges a draw
/// that names something else. Returns how many were named.
fn signed_draws(
    e: EffectName,
    draws: u64,
    options: &DiagnoseOptions,
    words: (&str, &str),
    on_miss: impl Fn(u64, f64, &cable_servo::identify::Diagnosis),
) -> u64 {
    let mut named = 0;
    for seed in 0..draws {
        let sign = if seed % 2 == 0 { -1.0 } else { 1.0 };
        let v = sign * support::rates::size_of(e, seed + 100);
        let sc = scenario(seed % 4 >= 2);
        let log = truth(&sc, &[(e, v)], 100 + seed);
        let d = diagnose(&sc, &[log], options).expect("diagnosis");
        let est = effect_value(&d, e);
        eprintln!(
            "{} {v:.3e} seed {seed}: {} {est:?} base {:.4} ext {:.4} floor {:.4}",
            e.as_str(),
            d.cause,
            d.rmse_base_mrad,
            d.rmse_extended_mrad,
            d.noise_floor_mrad
        );
        if d.cause != e.as_str() {
            on_miss(seed, v, &d);
            continue;
        }
        named += 1;
        let est = est.expect("a named effect has a size");
        assert!(
            (est - v).abs() <= size_tolerance(e) * v.abs(),
            "seed {seed}: {est:e} for {v:e}"
        );
        let said = d
            .directions
            .iter()
            .find(|x| x.effect == e.as_str())
            .expect("the direction of a signed effect");
        let want = if v < 0.0 { words.0 } else { words.1 };
        assert!(said.meaning.contains(want), "{v:e}: {}", said.meaning);
    }
    named
}

/// A link that gives way with the load (negative compliance: it adds to the spans' own
/// stretch) is found and sized as well as a drive stiffer than the cable model, and the
/// report says which way it went.
#[test]
fn finds_load_compliance_of_either_sign() {
    let e = EffectName::LoadCompliance;
    let words = ("gives way with the load", "stiffer");
    let named = signed_draws(e, SEEDS_EXTENDED, &opts_every(), words, |_, _, _| {});
    let (rate, _) = claimed_rates(e);
    assert!(
        named >= (rate * SEEDS_EXTENDED as f64).ceil() as u64,
        "named {named}/{SEEDS_EXTENDED}"
    );
}

/// A preload that rises through the record (the backlash shrinking with time) is found and
/// sized as one that relaxes is, and the report says which way it went; with the rate
/// bounded at zero the rising one could not be fitted at all. Eight draws. A rising preload
/// shows less than a falling one of the same rate (the backlash is convex in the preload:
/// over a 30 s record 0.5 %/s raises it 15 % and shrinks the backlash less than a 15 % fall
/// grows it), and at the smallest sizes its signature can stay within the noise: one miss
/// is allowed, and it must be `none`, never another name (24 rising draws: 23 named, the
/// miss at 5.2e-3 /s whose base model left 1.03 noise floors).
#[test]
fn finds_preload_relaxation_of_either_sign() {
    let e = EffectName::PreloadRelaxation;
    let draws = 8;
    let words = ("preload rises", "preload falls");
    let named = signed_draws(e, draws, &opts(), words, |seed, v, d| {
        assert_eq!(d.cause, "none", "seed {seed}, {v:e}: {:?}", d.causes);
    });
    assert!(named + 1 >= draws, "named {named}/{draws}");
}

/// Logs recorded faster than the diagnosis's 200 Hz rows are averaged down, and the row
/// holding a reversal averages the drum's states on both sides of the brake's flip. A
/// bearing friction at 500 Hz (rows of two samples) and at 1 kHz (five): named and sized
/// within 10 % on every draw. Scored with those rows, a drum runout was named in its
/// place on six of eight 500 Hz draws.
#[test]
fn bearing_friction_is_named_on_logs_faster_than_the_rows() {
    let e = EffectName::BearingFriction;
    // (rate, length, seed of the size, seed of the log)
    let draws = [
        (500.0, 30.0, 50u64, 9000u64),
        (500.0, 30.0, 52, 9002),
        (1000.0, 20.0, 50, 9000),
    ];
    for (rate_hz, duration_s, seed, log_seed) in draws {
        let sc = scenario(false);
        let v = support::rates::size_of(e, seed);
        let o = TruthOptions {
            duration_s: Some(duration_s),
            sample_rate_hz: Some(rate_hz),
            ..TruthOptions::default()
        };
        bearing_friction_is_named(&sc, v, log_seed, &o, &format!("{rate_hz} Hz, seed {seed}"));
    }
}

/// A log of the truth with a bearing friction of `v` (N m): named and sized within 10 %.
fn bearing_friction_is_named(sc: &Scenario, v: f64, log_seed: u64, o: &TruthOptions, draw: &str) {
    let e = EffectName::BearingFriction;
    let log = truth_log(sc, &[(e, v)], log_seed, o).expect("truth").log;
    let d = diagnose(sc, &[log], &opts()).expect("diagnosis");
    let est = effect_value(&d, e);
    let what = format!("{draw}: {v:.4} N m hidden, {} {est:?}", d.cause);
    eprintln!("{what}");
    assert_eq!(d.cause, e.as_str(), "{what}");
    let est = est.expect("a named effect has a size");
    assert!((est / v - 1.0).abs() <= 0.1, "{what}");
}

/// A sine with an offset and a phase reverses between rows, 1.5 ms before one. A bearing
/// friction flips where the drum reverses, and so must the fitted direction of motion:
/// flipped where the speed was confirmed a row later, that row carried the friction the
/// wrong way and a drum runout was named in its place on both draws. Named and sized
/// within 10 %.
#[test]
fn bearing_friction_is_named_where_the_reversals_fall_between_rows() {
    let e = EffectName::BearingFriction;
    let text = include_str!("../scenarios/gimbal_ident.toml");
    let sets = [
        "quasi_static.motion.offset_rad=3.0".to_string(),
        "quasi_static.motion.phase_rad=1.0".to_string(),
    ];
    let sc = Scenario::from_toml(text, "gimbal", "gimbal", &sets).expect("scenario");
    for seed in [0u64, 1] {
        let v = support::rates::size_of(e, 50 + seed);
        let o = TruthOptions::default();
        bearing_friction_is_named(&sc, v, 9000 + seed, &o, &format!("seed {seed}"));
    }
}

/// The same log seen from the other side: input, output and load negated, the two spans
/// swapped. Nothing in the model may assume which way the drive turns or is loaded, so the
/// diagnosis must be the same drive: the same causes, the same held-out errors and sizes
/// (to rounding), a compliance of the same sign, and only a drift of the output angle
/// reversed, with its direction in words.
#[test]
fn a_drive_turning_the_other_way_is_the_same_drive() {
    use EffectName::{
        AngleDependentRatio as Ratio, DistributedFrictionMemory as Memory,
        InputPulleyRunout as Runout, LoadCompliance as Compliance, ThermalDrift as Drift,
    };
    let mirrored = |log: &BenchLog| {
        let neg = |v: &[f64]| v.iter().map(|x| -x).collect::<Vec<f64>>();
        BenchLog {
            theta_in_rad: neg(&log.theta_in_rad),
            theta_out_rad: neg(&log.theta_out_rad),
            load_nm: neg(&log.load_nm),
            tension_upper_n: log.tension_lower_n.clone(),
            tension_lower_n: log.tension_upper_n.clone(),
            motor_current_a: log.motor_current_a.as_deref().map(neg),
            ..log.clone()
        }
    };
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * a.abs().max(b.abs());
    // (effects with the sign of their size, seed)
    let cases = [
        ([(Compliance, -1.0), (Memory, 1.0)], 701u64),
        ([(Ratio, 1.0), (Memory, 1.0)], 711),
        ([(Runout, 1.0), (Drift, 1.0)], 721),
    ];
    for (effs, s) in cases {
        let effects: Vec<(EffectName, f64)> = effs
            .iter()
            .map(|(e, sign)| (*e, sign * support::rates::size_of(*e, s)))
            .collect();
        let sc = scenario(true);
        let log = truth(&sc, &effects, s);
        let a = diagnose(&sc, std::slice::from_ref(&log), &opts_every()).expect("diagnosis");
        let b = diagnose(&sc, &[mirrored(&log)], &opts_every()).expect("diagnosis");
        let what = format!(
            "{effects:?}: {:?} {:.6} -> {:.6} mrad; mirrored {:?} {:.6} -> {:.6} mrad",
            a.causes,
            a.rmse_base_mrad,
            a.rmse_extended_mrad,
            b.causes,
            b.rmse_base_mrad,
            b.rmse_extended_mrad
        );
        eprintln!("{what}");
        let mut want: Vec<&str> = effects.iter().map(|(e, _)| e.as_str()).collect();
        want.sort_unstable();
        let mut got: Vec<&str> = a.causes.iter().map(String::as_str).collect();
        got.sort_unstable();
        assert_eq!(got, want, "{what}");
        assert_eq!(a.causes, b.causes, "{what}");
        assert!(close(a.rmse_base_mrad, b.rmse_base_mrad), "{what}");
        assert!(close(a.rmse_extended_mrad, b.rmse_extended_mrad), "{what}");
        for (e, _) in &effects {
            let (va, vb) = (effect_value(&a, *e), effect_value(&b, *e));
            let (va, vb) = (va.expect("sized"), vb.expect("sized"));
            let flips = if *e == Drift { -1.0 } else { 1.0 };
            assert!(close(va, flips * vb), "{e}: {va:e} against {vb:e}; {what}");
        }
        for x in &a.directions {
            let y = b.directions.iter().find(|y| y.effect == x.effect);
            let y = y.expect("the same directions");
            if x.effect == Drift.as_str() {
                assert_ne!(x.meaning, y.meaning, "{}", x.meaning);
            } else {
                assert_eq!(x.meaning, y.meaning);
            }
        }
    }
}

/// Below the smallest size of the ranges above: at a tenth of it an effect may be found
/// or drown in the noise, but the answer is the right name or `none`, never another effect
/// and never `unexplained`; at a thousandth (a few percent of the noise floor) it is `none`.
#[test]
fn effects_below_the_smallest_size_are_none_or_named_right() {
    for (scale, must_be_none) in [(0.1, false), (1e-3, true)] {
        for e in EffectName::EVERY {
            for seed in 0..2u64 {
                let v = scale * size_range(e).0;
                let sc = scenario(seed == 1);
                let log = truth(&sc, &[(e, v)], 500 + seed);
                let d = diagnose(&sc, &[log], &opts()).unwrap();
                eprintln!("below: {e} at {v:e}: {}", d.cause);
                if must_be_none || d.cause != e.as_str() {
                    assert_eq!(d.cause, "none", "{e} at {v:e}: {:?}", d.candidates);
                }
            }
        }
    }
}

fn clean_none(o: &DiagnoseOptions, what: &str) {
    let none = clean_rate(SEEDS, o, what);
    let need = (0.95 * SEEDS as f64).ceil() as usize;
    assert!(
        none >= need,
        "clean logs ({what}) called none {none}/{SEEDS}"
    );
}

#[test]
fn clean_logs_are_none() {
    clean_none(&opts_library(), "library searched");
}

#[test]
fn clean_logs_are_none_with_every_effect_searched() {
    clean_none(&opts_every(), "every effect searched");
}

#[test]
fn resonance_is_unexplained() {
    for seed in 0..4u64 {
        let sc = scenario(seed % 2 == 1);
        let o = TruthOptions {
            ringing: Some(Ringing {
                amplitude_rad: 1e-4 * (1.0 + seed as f64 * 0.5),
                frequency_hz: 3.0 + seed as f64,
                decay_s: 0.5,
            }),
            ..TruthOptions::default()
        };
        let log = truth_log(&sc, &[], 2000 + seed, &o).unwrap().log;
        let d = diagnose(&sc, &[log], &opts()).unwrap();
        assert_eq!(d.cause, "unexplained", "seed {seed}: {:?}", d.candidates);
        let w = d
            .residual_whiteness
            .expect("a 30 s log is long enough to test");
        assert!(
            w.p_value < 1e-2,
            "seed {seed}: ringing left a white residual {w:?}"
        );
    }
}

/// Pairs of effects with different signatures (angle-periodic with time drift, velocity
/// with load jumps, drum-periodic with scale), each found and sized within 10 %.
#[test]
fn two_effects_are_both_named() {
    let pairs = [
        [
            (EffectName::InputPulleyRunout, 1.0e-3),
            (EffectName::ThermalDrift, 3e-6),
        ],
        [
            (EffectName::EncoderDelay, 6e-4),
            (EffectName::BearingFriction, 0.2),
        ],
        [
            (EffectName::OutputDrumRunout, 1.5e-4),
            (EffectName::EncoderScaleError, 1e-4),
        ],
    ];
    for (k, effects) in pairs.iter().enumerate() {
        let sc = scenario(k == 1);
        let log = truth(&sc, effects, 7 + k as u64);
        let d = diagnose(&sc, &[log], &opts()).unwrap();
        let mut want: Vec<&str> = effects.iter().map(|(e, _)| e.as_str()).collect();
        let mut got: Vec<&str> = d.causes.iter().map(String::as_str).collect();
        want.sort_unstable();
        got.sort_unstable();
        assert_eq!(got, want, "{:?}", d.candidates);
        for (e, v) in effects {
            let est = effect_value(&d, *e).unwrap_or(f64::NAN);
            let est = match e {
                EffectName::InputPulleyRunout | EffectName::OutputDrumRunout => est.abs(),
                _ => est,
            };
            assert!((est - v).abs() < 0.1 * v, "{e}: {est} vs {v}");
        }
    }
}

/// A large smooth error adds its own sample-to-sample differences to the base model's
/// residual, from which the noise floor is first estimated: an input pulley runout at the
/// top of its range (2e-3) raised that estimate to about 1.8 times the noise, and the
/// search then stopped once the runout was found, as if what was left were noise. The
/// floor the diagnosis reports must be that of the same log's noise without the effects
/// (the same truth seed, so the same noise), and a bearing friction at the bottom of its
/// range beside the runout must still be named and sized.
#[test]
fn a_small_effect_beside_a_large_one_is_named_and_the_floor_stays_the_noise() {
    for seed in 0..3u64 {
        let sc = scenario(seed % 2 == 1);
        let bf = 0.1 + 0.01 * seed as f64;
        let effects = [
            (EffectName::InputPulleyRunout, 2e-3),
            (EffectName::BearingFriction, bf),
        ];
        let d = diagnose(&sc, &[truth(&sc, &effects, 40 + seed)], &opts()).unwrap();
        let clean = diagnose(&sc, &[truth(&sc, &[], 40 + seed)], &opts()).unwrap();
        assert!(
            d.noise_floor_mrad <= 1.1 * clean.noise_floor_mrad,
            "seed {seed}: floor {} mrad beside the runout, {} mrad on the same noise alone",
            d.noise_floor_mrad,
            clean.noise_floor_mrad
        );
        let mut got: Vec<&str> = d.causes.iter().map(String::as_str).collect();
        got.sort_unstable();
        assert_eq!(
            got,
            ["bearing_friction", "input_pulley_runout"],
            "seed {seed}: {:?}",
            d.candidates
        );
        let est = effect_value(&d, EffectName::BearingFriction).unwrap_or(f64::NAN);
        assert!((est - bf).abs() < 0.1 * bf, "seed {seed}: {est} vs {bf}");
    }
}

/// A delayed output encoder reads, at the log's first sample, where the axis was a delay
/// earlier. Both log generators once held the first value there instead, a jump of the
/// delay times the speed (2.4 mrad at 2 ms on this scan) in one row that no delayed
/// encoder makes; the diagnosis, fitting the delay as speed times lag throughout, left it
/// as 0.043 mrad held out, 7.5 times the noise floor, and said more was going on. With
/// the motion continued back in time, the delay at the top of its range leaves the
/// noise, on the tool's own synthetic logs and on the independent truth's.
#[test]
fn a_delay_at_the_top_of_its_range_leaves_only_the_noise() {
    use cable_servo::identify::{synthesize, SynthOptions};
    for seed in 0..2u64 {
        let sc = scenario(seed == 1);
        let hidden = [(EffectName::EncoderDelay, 2e-3)];
        let logs = [
            (
                "synth",
                synthesize(&sc, &hidden, seed, &SynthOptions::default()).unwrap(),
            ),
            ("truth", truth(&sc, &hidden, 60 + seed)),
        ];
        for (what, log) in logs {
            let d = diagnose(&sc, &[log], &opts()).unwrap();
            assert_eq!(
                d.cause, "encoder_delay",
                "{what} seed {seed}: {:?}",
                d.candidates
            );
            assert!(
                !d.unexplained_structure,
                "{what} seed {seed}: {:.4} mrad held out over a floor of {:.4}",
                d.rmse_extended_mrad, d.noise_floor_mrad
            );
        }
    }
}

/// A 1 ms encoder delay on `synth` logs is named alone: the generator reads a delayed
/// encoder off the cubic through the nearest samples. Read off a straight line between
/// samples 10 ms apart, the 0.1 Hz sine carried a scale error of about 1.8e-6 beside the
/// delay, and an output drum runout of 2.8e-6 (14 sigma) was named second on four of six
/// seeds.
#[test]
fn a_delay_alone_is_named_alone() {
    named_alone_on_synth_logs(EffectName::EncoderDelay, 1e-3, &opts());
}

/// `effect` of `size` hidden alone in `synth` logs of seeds 1 to 4 is the only effect the
/// diagnosis with `o` names.
fn named_alone_on_synth_logs(effect: EffectName, size: f64, o: &DiagnoseOptions) {
    use cable_servo::identify::{synthesize, SynthOptions};
    let sc = scenario(false);
    for seed in 1..=4u64 {
        let log = synthesize(&sc, &[(effect, size)], seed, &SynthOptions::default()).unwrap();
        let d = diagnose(&sc, &[log], o).unwrap();
        assert_eq!(
            d.causes,
            [effect.as_str()],
            "seed {seed}: {:?}",
            d.candidates
        );
    }
}

/// The significance gate shares its 5 % among the candidates of a round (Bonferroni): two
/// standard deviations for one, 2.73 for eight, 2.84 for eleven, rising with more.
#[test]
fn the_size_gate_grows_with_the_candidates_judged() {
    use cable_servo::identify::size_sigmas;
    assert_eq!(size_sigmas(0), 2.0);
    assert_eq!(size_sigmas(1), 2.0);
    assert!((size_sigmas(8) - 2.734).abs() < 1e-3, "{}", size_sigmas(8));
    assert!(
        (size_sigmas(11) - 2.838).abs() < 1e-3,
        "{}",
        size_sigmas(11)
    );
    assert!(
        (size_sigmas(15) - 2.935).abs() < 1e-3,
        "{}",
        size_sigmas(15)
    );
    assert!((1..40).all(|m| size_sigmas(m + 1) >= size_sigmas(m)));
}

/// A friction memory alone on `synth` logs (every effect searched) is named alone: with a
/// gate of two standard deviations for each of the eleven candidates of the second round,
/// an encoder scale error of about 1.4e-6 (2.4 sigma) was named beside it on two of these
/// four seeds.
#[test]
fn a_friction_memory_alone_is_named_alone() {
    named_alone_on_synth_logs(EffectName::DistributedFrictionMemory, 2e-4, &opts_every());
}

/// Two effects that share the structure so that neither passes a strict gate alone (each
/// explains less than 90 % of it) are found together by the joint search of pairs; with
/// the pair search's fallback only, a clean log stays `none`.
#[test]
fn a_pair_that_passes_only_together_is_found() {
    let effects = [
        (EffectName::EncoderDelay, 6e-4),
        (EffectName::InputPulleyRunout, 1e-3),
    ];
    for seed in 0..3u64 {
        let mut sc = scenario(seed == 1);
        if let Some(i) = sc.identify.as_mut() {
            i.min_explained_fraction = 0.9;
        }
        let log = truth(&sc, &effects, 40 + seed);
        let d = diagnose(&sc, &[log], &opts()).expect("diagnosis");
        let mut got: Vec<&str> = d.causes.iter().map(String::as_str).collect();
        got.sort_unstable();
        assert_eq!(
            got,
            ["encoder_delay", "input_pulley_runout"],
            "seed {seed}: {:?}",
            d.candidates
        );
        let pair = d
            .candidates
            .iter()
            .find(|c| c.accepted)
            .expect("an accepted candidate");
        assert!(
            pair.name.contains(" + ") && pair.verdict.contains("pair"),
            "seed {seed}: the single effects passed alone: {:?}",
            d.candidates
        );
        for (e, v) in effects {
            let est = effect_value(&d, e).expect("sized").abs();
            assert!((est - v).abs() < 0.1 * v, "seed {seed}: {e} {est} vs {v}");
        }
        let clean = truth(&sc, &[], 60 + seed);
        let d = diagnose(&sc, &[clean], &opts()).expect("diagnosis");
        assert_eq!(d.cause, "none", "seed {seed}: {:?}", d.candidates);
    }
}

/// A pair must gain the threshold over each of its two alone. On clean scans at 0.4 Hz an
/// input pulley runout gains about 2.3 % alone and a ratio shape less; before, the two
/// passed together at 3.5 % and were named on three of twelve seeds of an outside check
/// (these two among them).
#[test]
fn a_pair_of_which_one_adds_nothing_is_not_named() {
    use cable_servo::identify::{synthesize, SynthOptions};
    let sc = support::rates::gimbal_changed("frequency_hz = 0.1", "frequency_hz = 0.4");
    for seed in [100u64, 104] {
        let log = synthesize(&sc, &[], seed, &SynthOptions::default()).unwrap();
        let d = diagnose(&sc, &[log], &opts()).expect("diagnosis");
        assert_eq!(d.cause, "none", "seed {seed}: {:?}", d.candidates);
    }
}

/// A balanced axis (no unbalance) loads the drive with a brake of one size throughout,
/// so a compliance trades against the cable modulus and its size cannot be told from
/// zero, though it brings the error to the noise. The answer says so and names it; before,
/// it named an encoder delay of -0.17 ms as all it found and said the library lacked
/// what the drive does.
#[test]
fn an_effect_that_fits_but_cannot_be_sized_is_named_as_such() {
    use cable_servo::identify::{synthesize, SynthOptions};
    let sc = support::rates::gimbal_changed("unbalance_nm = 0.3", "unbalance_nm = 0.0");
    let hidden = [(EffectName::LoadCompliance, 5e-4)];
    let log = synthesize(&sc, &hidden, 200, &SynthOptions::default()).unwrap();
    let d = diagnose(&sc, &[log], &opts()).expect("diagnosis");
    let text = cable_servo::report::diagnosis::summary_text(&d);
    assert!(
        text.contains("Not pinned: load_compliance")
            && text.contains("load_compliance would bring it to the noise"),
        "{text}"
    );
}

/// Three logs of one instrument; the middle one held out.
#[test]
fn several_logs_and_held_out_log() {
    let sc = scenario(false);
    let logs: Vec<_> = (0..3)
        .map(|s| {
            let o = TruthOptions {
                instrument_seed: Some(300),
                ..TruthOptions::default()
            };
            truth_log(&sc, &[(EffectName::EncoderDelay, 8e-4)], 300 + s, &o)
                .unwrap()
                .log
        })
        .collect();
    let d = diagnose(
        &sc,
        &logs,
        &DiagnoseOptions {
            holdout_logs: vec![1],
            ..DiagnoseOptions::default()
        },
    )
    .unwrap();
    assert_eq!(d.cause, "encoder_delay");
    let est = effect_value(&d, EffectName::EncoderDelay).unwrap();
    assert!((est - 8e-4).abs() < 8e-5, "{est}");
    assert!(d.play_operator.is_some());
    assert!(d.rmse_extended_mrad < d.rmse_base_mrad);
}

/// Three loads of one instrument whose friction, preload and modulus are all off the
/// scenario's; the calibration starts further off and must land on the instrument, each
/// parameter within three of its reported standard deviations plus the grid cable's own
/// error (its jumps are within 5e-5 of the oracle's, so 1 % covers the parameters).
#[test]
fn calibrates_modulus_preload_and_friction_with_uncertainty() {
    let inst = Instrument {
        friction_coefficient: 0.206,
        preload_n: 48.5,
        cable_modulus_n: 1.52e4,
    };
    let mut sc = scenario(false);
    sc.drive.cable_modulus_n = 1.0e4;
    sc.drive.preload_n = 70.0;
    sc.drive.friction_coefficient = 0.3;
    sc.identify.as_mut().unwrap().unknown = vec![
        "cable_modulus_n".into(),
        "preload_n".into(),
        "friction_coefficient".into(),
    ];
    let logs: Vec<_> = [0.3, 0.7, 1.2]
        .iter()
        .enumerate()
        .map(|(k, b)| {
            let mut s = scenario(false);
            s.load.brake_nm = *b;
            let o = TruthOptions {
                instrument: Some(inst),
                ..TruthOptions::default()
            };
            truth_log(&s, &[], 400 + k as u64, &o).unwrap().log
        })
        .collect();
    let d = diagnose(&sc, &logs, &opts()).unwrap();
    for (name, truth) in [
        ("cable_modulus_n", inst.cable_modulus_n),
        ("preload_n", inst.preload_n),
        ("friction_coefficient", inst.friction_coefficient),
    ] {
        let g = d
            .params
            .iter()
            .find(|p| p.name == name)
            .unwrap_or_else(|| panic!("{name} not calibrated: {:?}", d.params));
        // The white-residual +- (the narrower, the stricter test).
        eprintln!("{name}: {} +- {} (truth {truth})", g.value, g.std_white);
        assert!(g.std_white > 0.0 && g.std_white.is_finite(), "{g:?}");
        assert!(
            (g.value - truth).abs() <= 3.0 * g.std_white + 0.01 * truth,
            "{name}: {} +- {} against the instrument's {truth}",
            g.value,
            g.std_white
        );
    }
    assert_eq!(d.cause, "none", "{:?}", d.candidates);
}

#[test]
fn log_round_trip_and_errors_name_line() {
    let sc = scenario(false);
    let log = truth(&sc, &[], 5);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.csv");
    write_bench_log(&p, &log).unwrap();
    let back = read_bench_log(&p).unwrap();
    assert_eq!(back.len(), log.len());
    let text = std::fs::read_to_string(&p).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let header = lines.iter().position(|l| !l.starts_with('#')).unwrap();
    let bad_line = header + 3;
    let mut v: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
    v[bad_line - 1] = "0.020000,abc,0.0,0.0".to_string();
    std::fs::write(&p, v.join("\n")).unwrap();
    let err = read_bench_log(&p).unwrap_err().to_string();
    assert!(
        err.contains("a.csv") && err.contains(&format!("line {bad_line}")) && err.contains("abc"),
        "{err} (line {bad_line})"
    );
    let d = diagnose(&sc, &[], &opts());
    assert!(d.is_err());
}

#[test]
fn writes_report_and_model() {
    let sc = scenario(false);
    let log = truth(&sc, &[(EffectName::InputPulleyRunout, 1e-3)], 9);
    let d = diagnose(&sc, &[log], &DiagnoseOptions::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let files = cable_servo::report::diagnosis::write_diagnosis(dir.path(), &sc, &d, None).unwrap();
    assert!(files.iter().all(|f| f.exists()));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("diagnosis.json")).unwrap())
            .unwrap();
    assert_eq!(json["cause"], "input_pulley_runout");
    for k in [
        "causes",
        "rmse_base_mrad",
        "rmse_extended_mrad",
        "gain_percent",
        "params",
        "candidates",
    ] {
        assert!(json.get(k).is_some(), "{k}");
    }
    // What made it, as every result records.
    assert_eq!(json["program_version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(json["complete"], true);
    assert_eq!(json["scenario_name"], sc.name());
    assert!(
        json["scenario"]["drive"]["preload_n"].is_number(),
        "{}",
        json["scenario"]
    );
    let m = dir.path().join("model.toml");
    cable_servo::report::diagnosis::save_model(&m, &sc, &d).unwrap();
    let back = Scenario::load(m.to_str().unwrap(), &[]).unwrap();
    let eps = back.effects.unwrap().input_pulley_runout.unwrap();
    assert!((eps - 1e-3).abs() < 1e-4, "{eps}");
}

#[test]
fn shipped_davinci_scenario_loads_with_effects() {
    let sc = Scenario::load("scenarios/davinci_tool4.toml", &[]).unwrap();
    let fx = sc.effects.unwrap();
    assert!(
        fx.angle_dependent_ratio_coefs.is_some()
            && fx.load_compliance_rad_per_nm.is_some()
            && fx.friction_memory_weights.is_some()
    );
    assert!(fx.validate().is_ok());
    assert!(sc.identify.unwrap().is_unknown("ratio"));
    let err = Scenario::load(
        "scenarios/davinci_tool4.toml",
        &["effects.bearing_frictoin_nm=1".into()],
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("bearing_friction_nm"), "{err}");
}

/// The absolute gain an effect must bring (`identify.min_gain_mrad`, 0.3 mrad on real
/// logs): a runout that is found by default is refused when its gain in mrad falls short,
/// with that reason, and the answer becomes `unexplained` (structure remains); the
/// threshold for `none` (`identify.none_within_floor`) moves the line between the two.
#[test]
fn absolute_gain_and_floor_thresholds_decide_as_set() {
    let sc = scenario(false);
    let log = truth(&sc, &[(EffectName::InputPulleyRunout, 3e-4)], 11);
    let d = diagnose(&sc, std::slice::from_ref(&log), &opts()).unwrap();
    assert_eq!(d.cause, "input_pulley_runout", "{:?}", d.candidates);
    let gain_mrad = d.rmse_base_mrad - d.rmse_extended_mrad;
    let mut strict = sc.clone();
    if let Some(i) = strict.identify.as_mut() {
        i.min_gain_mrad = 2.0 * gain_mrad;
    }
    let d = diagnose(&strict, std::slice::from_ref(&log), &opts()).unwrap();
    assert_eq!(d.cause, "unexplained", "{:?}", d.candidates);
    assert!(
        d.candidates
            .iter()
            .any(|c| c.name == "input_pulley_runout" && c.verdict.contains("min_gain_mrad")),
        "{:?}",
        d.candidates
    );
    let ratio = d.rmse_base_mrad / d.noise_floor_mrad;
    assert!(
        1.1 * ratio <= 10.0,
        "the test needs a residual within 9 floors: {ratio}"
    );
    if let Some(i) = strict.identify.as_mut() {
        i.none_within_floor = 1.1 * ratio;
    }
    let d = diagnose(&strict, std::slice::from_ref(&log), &opts()).unwrap();
    assert_eq!(d.cause, "none", "ratio {ratio}");
}

/// A calibrated instrument is the baseline. Calibrated once on a log of a drive with a
/// compliant link (the diagnosis saved as a scenario, `[effects]` and all), a second log of
/// the same instrument that also has a pulley runout gets the runout named and sized on
/// top of it, the compliance not searched again and the saved model carrying both; a log
/// of the instrument as calibrated gets `none`.
#[test]
fn what_is_missing_is_found_on_top_of_a_calibrated_instrument() {
    let sc = scenario(false);
    let o = TruthOptions {
        instrument_seed: Some(77),
        ..TruthOptions::default()
    };
    let log = |fx: &[(EffectName, f64)], seed: u64| {
        truth_log(&sc, fx, seed, &o)
            .unwrap_or_else(|e| panic!("truth: {e}"))
            .log
    };
    let compliance = (EffectName::LoadCompliance, -5e-4);
    let d = diagnose(&sc, &[log(&[compliance], 1)], &opts_every()).expect("calibration");
    assert_eq!(d.cause, "load_compliance", "{:?}", d.candidates);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("calibrated.toml");
    cable_servo::report::diagnosis::save_model(&path, &sc, &d).unwrap();
    let calibrated = Scenario::load(path.to_str().unwrap(), &[]).unwrap();
    let c = calibrated
        .effects
        .as_ref()
        .and_then(|fx| fx.load_compliance_rad_per_nm)
        .expect("the calibrated compliance");

    let runout = (EffectName::InputPulleyRunout, 1e-3);
    let d = diagnose(&calibrated, &[log(&[compliance, runout], 2)], &opts_every()).unwrap();
    assert!(d.calibrated_model.is_some());
    assert_eq!(d.cause, "input_pulley_runout", "{:?}", d.candidates);
    assert!(
        d.candidates.iter().all(|s| s.name != "load_compliance"),
        "{:?}",
        d.candidates
    );
    let est = effect_value(&d, runout.0).expect("runout size");
    assert!(
        (est - runout.1).abs() <= size_tolerance(runout.0) * runout.1,
        "runout {est:e} for {:e}",
        runout.1
    );
    assert_eq!(d.effects.load_compliance_rad_per_nm, Some(c));
    assert!(d.effects.input_pulley_runout.is_some());
    assert!(d.rmse_extended_mrad < d.rmse_base_mrad);

    let d = diagnose(&calibrated, &[log(&[compliance], 3)], &opts_every()).unwrap();
    assert_eq!(d.cause, "none", "{:?}", d.candidates);
}

/// A log of the test instrument (instrument seed 77) with a load compliance `c`
/// (rad/(N m)), noise drawn from `seed`.
fn compliance_log(c: f64, seed: u64) -> BenchLog {
    let o = TruthOptions {
        instrument_seed: Some(77),
        ..TruthOptions::default()
    };
    truth_log(
        &scenario(false),
        &[(EffectName::LoadCompliance, c)],
        seed,
        &o,
    )
    .unwrap_or_else(|e| panic!("truth: {e}"))
    .log
}

/// The test instrument calibrated on one log with a link that gives way at -5e-4
/// rad/(N m), saved as a scenario at `path`; returns the calibrated compliance.
fn calibrate_compliance(path: &std::path::Path) -> f64 {
    let sc = scenario(false);
    let d = diagnose(&sc, &[compliance_log(-5e-4, 1)], &opts_every()).expect("calibration");
    assert_eq!(d.cause, "load_compliance", "{:?}", d.candidates);
    cable_servo::report::diagnosis::save_model(path, &sc, &d).unwrap();
    d.effects
        .load_compliance_rad_per_nm
        .expect("the calibrated compliance")
}

/// A carried encoder scale error is tried at another size also when the scenario frees
/// the ratio: the search on top of a calibrated instrument holds the ratio, so the two are
/// not the same column there. Before, the scale error was left out, and a log at twice the
/// calibrated scale error named a 3.2e-3 drum runout instead.
#[test]
fn a_carried_scale_error_is_resized_with_the_ratio_free() {
    use cable_servo::identify::{synthesize, SynthOptions};
    let sc = scenario(false);
    let log = |v: f64, seed: u64| {
        synthesize(
            &sc,
            &[(EffectName::EncoderScaleError, v)],
            seed,
            &SynthOptions::default(),
        )
        .unwrap()
    };
    let d = diagnose(&sc, &[log(0.002, 1)], &opts()).expect("calibration");
    assert_eq!(d.cause, "encoder_scale_error", "{:?}", d.candidates);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("calibrated.toml");
    cable_servo::report::diagnosis::save_model(&path, &sc, &d).unwrap();
    let free = Scenario::load(
        path.to_str().unwrap(),
        &["identify.unknown=[\"cable_modulus_n\",\"ratio\"]".to_string()],
    )
    .unwrap();
    let d = diagnose(&free, &[log(0.004, 2)], &opts()).unwrap();
    assert_eq!(d.cause, "encoder_scale_error", "{:?}", d.candidates);
    let r = d.resized.first().expect("resized");
    assert!((r.found - 0.004).abs() <= 0.02 * 0.004, "{r:?}");
}

/// A term the scenario marks as belonging to each log (`identify.per_log`) is refitted on
/// a new log before the log is judged, and not searched on top: a jaw gripped harder on
/// the new log is the instrument as calibrated, not a new effect. Unmarked, the same log
/// leaves the calibrated model a larger error.
#[test]
fn a_term_marked_per_log_is_refitted_on_each_log() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("calibrated.toml");
    let c0 = calibrate_compliance(&path);
    let path = path.to_str().unwrap();
    let log = compliance_log;

    let truth = -9e-4;
    let new_log = log(truth, 2);
    let plain = diagnose(
        &Scenario::load(path, &[]).unwrap(),
        std::slice::from_ref(&new_log),
        &opts_every(),
    )
    .unwrap();
    let marked_scenario = Scenario::load(
        path,
        &["identify.per_log=[\"load_compliance\"]".to_string()],
    )
    .unwrap();
    let d = diagnose(&marked_scenario, &[new_log], &opts_every()).unwrap();
    let c = d
        .calibrated_model
        .as_ref()
        .expect("judged against the instrument");
    let unmarked = plain.calibrated_model.as_ref().expect("judged");
    assert_eq!(d.cause, "none", "{:?}", d.candidates);
    assert!(
        d.candidates.iter().all(|s| s.name != "load_compliance"),
        "{:?}",
        d.candidates
    );
    assert_eq!(c.refitted_per_log, ["encoder zero", "load_compliance"]);
    let added = c.per_log_terms[0].values[0].value;
    assert!(
        ((c0 + added) - truth).abs() <= 0.1 * truth.abs(),
        "calibrated {c0:e} + this log's {added:e} against {truth:e}"
    );
    let (marked, unmarked) = (
        c.rmse_mrad.expect("the drive carries the log"),
        unmarked.rmse_mrad.expect("the drive carries the log"),
    );
    assert!(
        marked < 0.5 * unmarked,
        "refitted {marked} mrad against {unmarked} mrad as calibrated"
    );
    assert!(cable_servo::report::diagnosis::summary_text(&d)
        .contains("encoder zero and its own load_compliance fitted"));
}

/// A term the calibration carries, held at one size for every log (not marked per log),
/// is tried on top at another size: logs of the instrument with a link that gives way
/// less, more, or the other way get it named and sized within 10 % (the calibrated size
/// plus the change), two draws each; two logs at -7e-4 and -1e-3 judged together share a
/// size between theirs, and each log's own is told within 10 %. On six logs of the
/// instrument as calibrated nothing is resized, and the answer is `none` on all but at
/// most one (the clean-log rate of the library search is 0.95).
#[test]
fn a_carried_term_at_another_size_is_found_on_top() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("calibrated.toml");
    let c0 = calibrate_compliance(&path);
    let calibrated = Scenario::load(path.to_str().unwrap(), &[]).unwrap();
    let log = compliance_log;

    for (truth, seed) in [
        (-2e-4, 2),
        (-2e-4, 3),
        (-9e-4, 4),
        (-9e-4, 5),
        (5e-4, 6),
        (5e-4, 7),
    ] {
        let d = diagnose(&calibrated, &[log(truth, seed)], &opts_every()).unwrap();
        let what = format!("compliance {truth:e} (seed {seed}): {:?}", d.candidates);
        assert_eq!(d.cause, "load_compliance", "{what}");
        assert_eq!(d.resized.len(), 1, "{what}");
        let r = &d.resized[0];
        assert_eq!(r.calibrated, c0, "{what}");
        assert!(
            (r.found - truth).abs() <= 0.1 * truth.abs(),
            "{what}: found {:e}",
            r.found
        );
        assert_eq!(
            d.effects.load_compliance_rad_per_nm,
            Some(r.found),
            "{what}"
        );
        let text = cable_servo::report::diagnosis::summary_text(&d);
        assert!(
            text.contains("CAUSE: load_compliance at another size than calibrated"),
            "{text}"
        );
    }
    // Two logs that differ share one size between theirs; each log's own is told apart.
    let both = [log(-7e-4, 2), log(-1e-3, 4)];
    let d = diagnose(&calibrated, &both, &opts_every()).unwrap();
    let r = d.resized.first().expect("resized on the two logs");
    assert_eq!(r.per_log.len(), 2, "{r:?}");
    for ((_, own), truth) in r.per_log.iter().zip([-7e-4, -1e-3]) {
        assert!((own - truth).abs() <= 0.1 * truth.abs(), "{r:?}");
    }
    assert!(r.found < -7e-4 && r.found > -1e-3, "{r:?}");

    let mut named = Vec::new();
    for seed in 8..14 {
        let d = diagnose(&calibrated, &[log(-5e-4, seed)], &opts_every()).unwrap();
        assert!(d.resized.is_empty(), "seed {seed}: {:?}", d.candidates);
        assert_eq!(
            d.effects.load_compliance_rad_per_nm,
            Some(c0),
            "seed {seed}"
        );
        if d.cause != "none" {
            named.push((seed, d.cause));
        }
    }
    assert!(
        named.len() <= 1,
        "named on the calibrated instrument: {named:?}"
    );
}

/// Pairs of the multi-wrap effects hidden together, three draws each (every effect
/// searched): each pair named whole (both and nothing else), and both sized within 10 %,
/// on at least the draws `docs/diagnose.md` states. The ratio shape with the friction
/// memory, and a link that gives way with the load (negative compliance) with the memory,
/// are separated on every draw; a compliance beside the ratio shape, or a stiffer drive
/// (positive compliance) beside the memory, often is not, and the guide says so.
#[test]
fn pairs_of_multi_wrap_effects_are_both_named() {
    use EffectName::{
        AngleDependentRatio as Ratio, DistributedFrictionMemory as Memory,
        LoadCompliance as Compliance,
    };
    // (pair, sign of the first effect, seeds, draws named whole, draws also sized)
    let cases = [
        ((Ratio, Memory), 1.0, [0u64, 1, 2], 3, 3),
        ((Compliance, Memory), -1.0, [1, 3, 5], 3, 2),
        ((Ratio, Compliance), 1.0, [0, 1, 2], 2, 2),
        ((Compliance, Ratio), -1.0, [0, 1, 2], 1, 1),
        ((Compliance, Memory), 1.0, [0, 2, 4], 1, 0),
    ];
    let mut report = Vec::new();
    let mut short = Vec::new();
    for (k, ((a, b), sign, seeds, need_named, need_sized)) in cases.into_iter().enumerate() {
        let (mut named, mut sized) = (0, 0);
        for seed in seeds {
            let s = 500 + 10 * k as u64 + seed;
            let effects = [
                (a, sign * support::rates::size_of(a, s)),
                (b, support::rates::size_of(b, s)),
            ];
            let sc = scenario(seed % 2 == 1);
            let log = truth(&sc, &effects, s);
            let d = diagnose(&sc, &[log], &opts_every()).expect("diagnosis");
            let mut got: Vec<&str> = d.causes.iter().map(String::as_str).collect();
            got.sort_unstable();
            let mut want = vec![a.as_str(), b.as_str()];
            want.sort_unstable();
            let within = effects.iter().all(|(e, v)| {
                effect_value(&d, *e).is_some_and(|est| (est - v).abs() <= 0.1 * v.abs())
            });
            let sizes: Vec<String> = effects
                .iter()
                .map(|(e, v)| format!("{e} {v:.3e} -> {:?}", effect_value(&d, *e)))
                .collect();
            report.push(format!(
                "{a} + {b} seed {seed}: {got:?}, sized {within}; {}",
                sizes.join(", ")
            ));
            if got == want {
                named += 1;
                sized += usize::from(within);
            }
        }
        if named < need_named || sized < need_sized {
            short.push(format!(
                "{a} + {b}: named {named}/{}, need {need_named}; sized {sized}, need {need_sized}",
                seeds.len()
            ));
        }
    }
    assert!(short.is_empty(), "{short:?}\n{}", report.join("\n"));
}

/// A compliance beside a ratio shape at the small end of its range leaves, once the shape is
/// found, a residual that an encoder scale error, a drum runout and a bearing friction fit
/// as well as the compliance itself: the answer names the accepted one and, as not told
/// apart, the others, the hidden compliance among them. Single effects a little above the
/// noise floor, where every candidate's RMSE is close, keep a clear answer.
#[test]
fn candidates_the_log_cannot_tell_apart_are_named_as_such() {
    use EffectName::{AngleDependentRatio as Ratio, LoadCompliance as Compliance};
    for seed in [0u64, 2] {
        let s = 530 + seed;
        let effects = [
            (Compliance, -support::rates::size_of(Compliance, s)),
            (Ratio, support::rates::size_of(Ratio, s)),
        ];
        let sc = scenario(false);
        let d = diagnose(&sc, &[truth(&sc, &effects, s)], &opts_every()).expect("diagnosis");
        let offered: Vec<&str> = d
            .indistinguishable
            .iter()
            .flat_map(|t| {
                std::iter::once(t.accepted.as_str())
                    .chain(t.alternatives.iter().map(|a| a.name.as_str()))
            })
            .collect();
        assert!(
            d.causes.iter().any(|c| c == "angle_dependent_ratio")
                && offered.contains(&"load_compliance"),
            "seed {seed}: causes {:?}, not told apart {:?}",
            d.causes,
            d.indistinguishable
        );
        let text = cable_servo::report::diagnosis::summary_text(&d);
        assert!(text.contains("Not told apart: "), "{text}");
    }
    // A small compliance alone, where a drum runout brings the residual as far down, below
    // the noise floor: the runout is named, and the compliance beside it.
    let seed = 46;
    let sc = scenario(true);
    let v = support::rates::size_of(Compliance, seed);
    let d = diagnose(&sc, &[truth(&sc, &[(Compliance, v)], seed)], &opts()).expect("diagnosis");
    assert!(
        d.indistinguishable.iter().any(|t| {
            t.accepted == "load_compliance"
                || t.alternatives.iter().any(|a| a.name == "load_compliance")
        }),
        "compliance {v:.3e}: {} {:?}",
        d.cause,
        d.indistinguishable
    );
    // Found alone, each leaves a drum runout 0.5 % to 1.1 % behind in RMSE but well behind
    // in what it explains above the noise.
    for (e, seed) in [
        (EffectName::BearingFriction, 0u64),
        (EffectName::BearingFriction, 5),
        (Compliance, 2),
    ] {
        let sc = scenario(seed % 4 >= 2);
        let log = truth(&sc, &[(e, support::rates::size_of(e, seed))], seed);
        let d = diagnose(&sc, &[log], &opts()).expect("diagnosis");
        assert!(
            d.cause == e.as_str() && d.indistinguishable.is_empty(),
            "{e} seed {seed}: {} {:?}",
            d.cause,
            d.indistinguishable
        );
    }
}

/// A short clean log whose base model is within the noise threshold of `none` gets `none`:
/// before, a drum runout of 8e-5 +- 6.4e-5 (1.25 sigma) fitted to the noise of a 2 s log
/// gained 4 to 7 % held out and was named on four of these five seeds.
#[test]
fn short_clean_logs_are_none() {
    use cable_servo::identify::{synthesize, SynthOptions};
    let sc = Scenario::load("gimbal_ident", &["quasi_static.duration_s=2".into()]).unwrap();
    for seed in 1..=5u64 {
        let log = synthesize(&sc, &[], seed, &SynthOptions::default()).unwrap();
        let d = diagnose(&sc, &[log], &opts()).unwrap();
        assert_eq!(
            d.cause, "none",
            "seed {seed}: {:?} {:?}",
            d.causes, d.candidates
        );
    }
}

/// A fit that runs an effect onto the bound meaning none of it has not found the effect:
/// beside a 1 ms encoder delay, a cable transport over the least travel allowed (1e-4 rad)
/// was named second on every seed. Those logs carried the generator's interpolation error
/// (see `a_delay_alone_is_named_alone`); read off a cubic they leave nothing for a second
/// round, so this test now guards the answer but no longer brings a candidate onto its
/// bound: with the rule switched off it still passes. No log found since does; the rule
/// itself is held by the unit test `an_effect_on_the_bound_that_means_none_is_told`.
#[test]
fn an_effect_fitted_onto_its_none_bound_is_not_found() {
    use cable_servo::identify::{synthesize, SynthOptions};
    let sc = Scenario::load("gimbal_ident", &[]).unwrap();
    for seed in 1..=3u64 {
        let hidden = [(EffectName::EncoderDelay, 1e-3)];
        let log = synthesize(&sc, &hidden, seed, &SynthOptions::default()).unwrap();
        let d = diagnose(&sc, &[log], &opts()).unwrap();
        assert_eq!(d.cause, "encoder_delay", "seed {seed}: {:?}", d.causes);
        assert!(
            !d.causes.iter().any(|c| c == "cable_transport"),
            "seed {seed}: {:?}",
            d.causes
        );
    }
}

/// An effect whose fitted size is not told from zero is not found, nor given a direction:
/// beside a friction memory, a load compliance of -8.0e-6 +- 2.0e-5 was named second and
/// said to give way with the load.
#[test]
fn an_effect_whose_size_is_not_told_from_zero_is_not_found() {
    use cable_servo::identify::{synthesize, SynthOptions};
    let sc = Scenario::load("gimbal_ident", &[]).unwrap();
    let hidden = [(EffectName::DistributedFrictionMemory, 2e-4)];
    let log = synthesize(&sc, &hidden, 5, &SynthOptions::default()).unwrap();
    let d = diagnose(&sc, &[log], &opts_every()).unwrap();
    assert_eq!(d.cause, "distributed_friction_memory", "{:?}", d.causes);
    for p in d.params.iter().filter(|p| d.causes.contains(&p.name)) {
        // The gate judges on the white-residual +-.
        assert!(
            p.value.abs() >= 2.0 * p.std_white,
            "{} found at {} +- {}",
            p.name,
            p.value,
            p.std_white
        );
    }
    assert!(
        !d.causes.iter().any(|c| c == "load_compliance"),
        "{:?}",
        d.causes
    );
}

/// A drive that is a deadband and nothing else: the output is a play operator of the input
/// (half width 5 % of the stroke, between two of the friction memory's thresholds), with
/// white noise and the output encoder's quantisation. The play operator fitted to the log
/// is the truth, so no extension of the cable model can beat it held out: the effects the
/// search finds are kept in `causes`, but the verdict says "not established" and the
/// JSON's cause is `unexplained`, on a sine and a triangle scan.
#[test]
fn an_extension_the_play_operator_beats_is_not_established() {
    use cable_servo::identify::{synthesize, SynthOptions};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    for (seed, triangle) in [(21u64, false), (22, true)] {
        let sc = scenario(triangle);
        let mut log = synthesize(&sc, &[], seed, &SynthOptions::default()).unwrap();
        let ic = sc.drive.drum_radius_m / sc.drive.pulley_radius_m;
        let (lo, hi) = log
            .theta_in_rad
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        let r = 0.05 * (hi - lo) / ic;
        let q = std::f64::consts::TAU / 1_048_576.0;
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 1e-6).unwrap();
        let mut y = log.theta_in_rad[0] / ic;
        for (out, x) in log.theta_out_rad.iter_mut().zip(&log.theta_in_rad) {
            y = y.clamp(x / ic - r, x / ic + r);
            *out = ((y + noise.sample(&mut rng)) / q).round() * q;
        }
        let d = diagnose(&sc, &[log], &DiagnoseOptions::default()).unwrap();
        let play = d
            .play_operator
            .as_ref()
            .expect("the play operator is fitted");
        eprintln!(
            "seed {seed}: causes {:?}, extended {:.4} mrad, play operator {:.4}, base {:.4}, floor {:.4}",
            d.causes, d.rmse_extended_mrad, play.rmse_heldout_mrad, d.rmse_base_mrad, d.noise_floor_mrad
        );
        // The path under test: an extension was found, and it loses to the deadband.
        assert!(!d.causes.is_empty(), "seed {seed}: nothing found");
        assert!(
            play.rmse_heldout_mrad < d.rmse_extended_mrad,
            "seed {seed}: {} against {}",
            play.rmse_heldout_mrad,
            d.rmse_extended_mrad
        );
        assert_eq!(d.beats_play_operator, Some(false), "seed {seed}");
        assert_eq!(d.cause, "unexplained", "seed {seed}: {:?}", d.causes);
        let text = cable_servo::report::diagnosis::summary_text(&d);
        let verdict = text
            .lines()
            .find(|l| l.starts_with("CAUSE:"))
            .unwrap_or_else(|| panic!("seed {seed}: no verdict in\n{text}"));
        assert!(
            verdict.starts_with("CAUSE: not established") && verdict.contains("play operator"),
            "seed {seed}: {verdict}"
        );
        // The effects appear only as what the extended model held, never as the cause
        // with its meaning.
        for c in &d.causes {
            let e: EffectName = c.parse().unwrap();
            assert!(
                !verdict.contains(e.meaning()) && !verdict.starts_with(&format!("CAUSE: {c}")),
                "seed {seed}: {verdict}"
            );
        }
        let dir = tempfile::tempdir().unwrap();
        cable_servo::report::diagnosis::write_diagnosis(dir.path(), &sc, &d, None).unwrap();
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("diagnosis.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(json["cause"], "unexplained", "seed {seed}");
        assert_eq!(json["beats_play_operator"], false, "seed {seed}");
    }
}

/// A log whose input and output never move (the load cell still reading) is refused by
/// name, not judged: before, it got a verdict over a noise floor of 0.0000 mrad.
#[test]
fn a_log_without_motion_is_refused() {
    use cable_servo::identify::{synthesize, SynthOptions};
    let sc = Scenario::load("gimbal_ident", &[]).unwrap();
    let mut log = synthesize(&sc, &[], 3, &SynthOptions::default()).unwrap();
    log.source = "nomotion.csv".into();
    log.theta_in_rad.iter_mut().for_each(|v| *v = 0.0);
    log.theta_out_rad.iter_mut().for_each(|v| *v = 0.0);
    let err = diagnose(&sc, &[log], &opts())
        .map(|d| format!("cause {} over a floor of {}", d.cause, d.noise_floor_mrad))
        .expect_err("a log without motion");
    let msg = err.to_string();
    assert!(
        msg.contains("nomotion.csv") && msg.contains("does not move"),
        "{msg}"
    );
}

/// Sensor noise that comes in runs (a first-order autoregression, rho 0.95, 5 µrad,
/// beside the white noise and quantisation) widens every `+-` and says so; the same log
/// without it keeps the white `+-` and prints nothing of the kind.
#[test]
fn a_residual_in_runs_widens_the_uncertainties_and_says_so() {
    use cable_servo::identify::{synthesize, SynthOptions};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let sc = Scenario::load("gimbal_ident", &[]).unwrap();
    let clean = synthesize(&sc, &[], 11, &SynthOptions::default()).unwrap();
    let mut runs = clean.clone();
    let rho: f64 = 0.95;
    let w = Normal::new(0.0, 5e-6 * (1.0 - rho * rho).sqrt()).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let mut e = 0.0;
    for o in &mut runs.theta_out_rad {
        e = rho * e + w.sample(&mut rng);
        *o += e;
    }
    let d_clean = diagnose(&sc, &[clean], &opts()).unwrap();
    let d_runs = diagnose(&sc, &[runs], &opts()).unwrap();
    let text = cable_servo::report::diagnosis::summary_text(&d_runs);
    let r = d_runs.residual_runs.as_ref().expect("runs measured");
    let c = d_clean.residual_runs.as_ref().expect("runs measured");
    eprintln!("runs: {r:?}\nclean: {c:?}");
    // The closed form (1 + rho) / (1 - rho) = 39 for the autoregression alone; the white
    // noise and the encoders' quantisation beside it, and the fit taking up part of the slow
    // wander, bring the whole residual's down (12 samples here).
    assert!(r.correlation_samples > 5.0, "{r:?}");
    assert!(r.median_widening > 2.0, "{r:?}");
    for p in &d_runs.params {
        assert!(p.std >= p.std_white, "{p:?}");
    }
    assert!(
        text.contains("The +- allow for a residual that comes in runs"),
        "{text}"
    );
    assert!(c.correlation_samples < 1.5, "{c:?}");
    assert!(c.max_widening < 1.15, "{c:?}");
    let clean_text = cable_servo::report::diagnosis::summary_text(&d_clean);
    assert!(!clean_text.contains("comes in runs"), "{clean_text}");
}
