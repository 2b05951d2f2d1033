//! cable-servo: preloaded cable-drive physics, closed-loop gimbal simulation, design sweeps
//! and bench-log diagnosis for electro-optical pointing systems.
//!
//! The modules form four layers; each imports only from the layers below it (and the few
//! same-layer arrows listed in `tests/layering.rs`, which enforces this):
//!
//! | layer | modules | job |
//! |---|---|---|
//! | top | [`run`], [`design`], the `cable-servo` binary | orchestration and the command line |
//! | edge | [`scenario`], [`io`], [`plot`], [`report`] | scenario files, logs and tables, figures, result files |
//! | computation | [`closed_loop`], [`analysis`], [`study`], [`identify`], [`sweep`] | parameter structs in, result records out |
//! | bottom | [`physics`], [`signal`], [`metrics`], [`measurement`] | the drive's physics, signals, metrics, data in memory |

pub mod analysis;
pub mod closed_loop;
pub mod design;
pub mod fmu;
pub mod identify;
pub mod io;
pub mod measurement;
pub mod metrics;
pub mod physics;
pub mod plot;
pub mod progress;
pub mod report;
pub mod run;
pub mod scenario;
pub mod signal;
pub mod stats;
pub mod study;
pub mod sweep;

/// How a value that is not a number (a typed `nan`) reads in a message: in words, never
/// as Rust's `NaN`.
pub const NOT_A_NUMBER: &str = "not a number (nan)";

/// A number as shown in messages: plain for everyday magnitudes, in exponent form for very
/// large or small ones (`1e300`, not three hundred digits).
pub fn number(v: f64) -> String {
    if v.is_nan() {
        return NOT_A_NUMBER.to_string();
    }
    if v == 0.0 || !v.is_finite() || (1e-4..1e9).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// `v` to `digits` significant digits (at least 1), plain for everyday magnitudes and in
/// exponent form beyond them: `37.2510`, `0.00123457`, `1.23457e300`.
pub fn significant(v: f64, digits: usize) -> String {
    let digits = digits.max(1);
    if v.is_nan() {
        return NOT_A_NUMBER.to_string();
    }
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let magnitude = v.abs().log10().floor();
    if (-4.0..9.0).contains(&magnitude) {
        let decimals = (digits as f64 - 1.0 - magnitude).max(0.0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.*e}", digits - 1)
    }
}

/// `v` to at most 4 significant digits without trailing zeros: `0.01`, `7e-7`, `2.143`.
pub fn compact(v: f64) -> String {
    trimmed(v, 4)
}

/// `v` to `digits` significant digits with trailing zeros (and a bare point) removed.
fn trimmed(v: f64, digits: usize) -> String {
    let s = significant(v, digits);
    let (mantissa, exponent) = match s.find('e') {
        Some(i) => s.split_at(i),
        None => (s.as_str(), ""),
    };
    let mantissa = if mantissa.contains('.') {
        mantissa.trim_end_matches('0').trim_end_matches('.')
    } else {
        mantissa
    };
    format!("{mantissa}{exponent}")
}

/// `v` as users read it: at most 7 significant digits, no trailing zeros, exponent form
/// for very large or small magnitudes: `100.0001`, `1e300`, `-2.5e-12`.
pub fn readable(v: f64) -> String {
    trimmed(v, 7)
}

/// `v` with `decimals` decimals for everyday magnitudes (as `{:.N}` prints them), and as
/// [`readable`] beyond 1e9 in size, where fixed decimals would print hundreds of digits.
pub fn fixed(v: f64, decimals: usize) -> String {
    if v.is_finite() && v.abs() < 1e9 {
        format!("{v:.decimals$}")
    } else {
        readable(v)
    }
}

/// The message for a scenario value outside what is allowed: `v` as [`number`] shows it,
/// then `allowed` (e.g. `a finite number > 0`), worded the same for every key.
pub fn out_of_range(v: f64, allowed: &str) -> String {
    format!("{} is out of range: it must be {allowed}", number(v))
}

/// [`fixed`], except that a nonzero value too small for `decimals` keeps three
/// significant digits (`2.05e-8`, `0.000123`), where fixed decimals would print zero:
/// for messages, whose every number must be one a user can act on.
pub fn fixed_or_significant(v: f64, decimals: usize) -> String {
    if v != 0.0 && v.abs() < 0.5 * 10f64.powi(-(decimals.min(300) as i32)) {
        significant(v, 3)
    } else {
        fixed(v, decimals)
    }
}

/// `text` with every number written out in more than 17 digits (as Rust and serde print
/// `1e308`: three hundred of them) replaced by its [`readable`] form: the last guard of
/// the command line's messages, whatever built them. Digits that are part of a word
/// (`tool4_04`) are left alone.
pub fn long_numbers_compacted(text: &str) -> String {
    const LONGEST: usize = 17;
    let bytes = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < bytes.len() {
        let word_before = i > 0 && (bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_');
        if !bytes[i].is_ascii_digit() || word_before {
            let c = text[i..].chars().next().unwrap_or(' ');
            out.push(c);
            i += c.len_utf8();
            continue;
        }
        let start = i;
        let mut digits = 0;
        let mut point = false;
        while i < bytes.len() {
            match bytes[i] {
                b'0'..=b'9' => digits += 1,
                b'.' if !point && bytes.get(i + 1).is_some_and(u8::is_ascii_digit) => point = true,
                _ => break,
            }
            i += 1;
        }
        let token = &text[start..i];
        let word_after = bytes
            .get(i)
            .is_some_and(|b| b.is_ascii_alphabetic() || *b == b'_');
        match token.parse::<f64>() {
            Ok(v) if digits > LONGEST && !word_after => out.push_str(&readable(v)),
            _ => out.push_str(token),
        }
    }
    out
}

/// A duration as shown in messages: `40 s`, `12 min`, `3.5 h`, `9.2 days`.
pub fn duration_words(s: f64) -> String {
    if !s.is_finite() {
        return format!("{s} s");
    }
    if s < 120.0 {
        format!("{} s", (s * 10.0).round() / 10.0)
    } else if s < 7200.0 {
        format!("{} min", (s / 60.0).round())
    } else if s < 2.0 * 86400.0 {
        format!("{} h", (s / 360.0).round() / 10.0)
    } else {
        let days = s / 86400.0;
        if days < 1e4 {
            format!("{} days", (days * 10.0).round() / 10.0)
        } else {
            format!("{days:.1e} days")
        }
    }
}

#[cfg(test)]
mod words_tests {
    #[test]
    fn durations_read_as_words() {
        assert_eq!(super::duration_words(0.25), "0.3 s");
        assert_eq!(super::duration_words(45.0), "45 s");
        assert_eq!(super::duration_words(600.0), "10 min");
        assert_eq!(super::duration_words(43200.0), "12 h");
        assert_eq!(super::duration_words(9.0 * 86400.0), "9 days");
        assert_eq!(super::duration_words(3e15), "3.5e10 days");
    }

    #[test]
    fn significant_digits_never_run_to_hundreds() {
        assert_eq!(super::significant(37.251, 6), "37.2510");
        assert_eq!(super::significant(0.00123456789, 3), "0.00123");
        assert_eq!(super::significant(1.234567e300, 6), "1.23457e300");
        assert_eq!(super::significant(-2.5e-12, 2), "-2.5e-12");
        assert_eq!(super::significant(1e8, 3), "100000000");
        assert!(super::significant(f64::MAX, 6).len() < 16);
        assert_eq!(super::compact(0.01), "0.01");
        assert_eq!(super::compact(7.000000000000001e-7), "7e-7");
        assert_eq!(super::compact(2.14307), "2.143");
        assert_eq!(super::compact(1200.0), "1200");
        assert_eq!(super::readable(1e300), "1e300");
        assert_eq!(super::fixed(0.0, 3), "0.000");
        assert_eq!(super::fixed(2.0288e300, 3), "2.0288e300");
        assert_eq!(super::readable(100.00001), "100");
        assert_eq!(super::readable(100.0001), "100.0001");
        assert_eq!(super::readable(-1.23456789e-300), "-1.234568e-300");
    }

    #[test]
    fn a_number_too_small_for_its_decimals_keeps_its_digits() {
        assert_eq!(super::fixed_or_significant(0.75, 3), "0.750");
        assert_eq!(super::fixed_or_significant(0.0, 4), "0.0000");
        assert_eq!(super::fixed_or_significant(2.05e-8, 3), "2.05e-8");
        assert_eq!(super::fixed_or_significant(-0.000123, 2), "-0.000123");
        // Rounding up to the last decimal shown is not too small.
        assert_eq!(super::fixed_or_significant(0.06, 1), "0.1");
        assert_eq!(super::fixed_or_significant(0.04, 1), "0.0400");
        assert_eq!(super::fixed_or_significant(3e300, 1), "3e300");
        assert_eq!(super::fixed_or_significant(1e-300, 3), "1.00e-300");
    }

    #[test]
    fn long_numbers_in_messages_are_compacted() {
        let huge = format!("{}", 1e308_f64);
        let tiny = format!("{}", -1e-300_f64);
        assert!(huge.len() > 300 && tiny.len() > 300);
        let message =
            format!("invalid type: floating point `{huge}.0`, at {tiny} s; the count {huge}");
        assert_eq!(
            super::long_numbers_compacted(&message),
            "invalid type: floating point `1e308`, at -1e-300 s; the count 1e308"
        );
        // Everyday numbers, words with digits and non-ASCII text stay as they are.
        let plain = "tool4_04.csv line 12: 0.1 mrad at 20000 Hz, 12345678901234567 µs";
        assert_eq!(super::long_numbers_compacted(plain), plain);
        let tagged = format!("x{huge}y");
        assert_eq!(super::long_numbers_compacted(&tagged), tagged);
    }
}
