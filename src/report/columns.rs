//! Table columns in words: a column's name ends in its unit (`preload_n`, `load_nm`,
//! `reversal_mrad`), which a figure spells out as `preload [N]`.

/// Unit words a column name may end in, and how a figure writes them.
const UNITS: &[(&str, &str)] = &[
    ("n", "N"),
    ("nm", "N m"),
    ("mrad", "mrad"),
    ("urad", "urad"),
    ("rad", "rad"),
    ("deg", "deg"),
    ("hz", "Hz"),
    ("khz", "kHz"),
    ("s", "s"),
    ("ms", "ms"),
    ("us", "us"),
    ("m", "m"),
    ("mm", "mm"),
    ("um", "um"),
    ("m2", "m^2"),
    ("kg", "kg"),
    ("a", "A"),
    ("v", "V"),
    ("w", "W"),
    ("ohm", "ohm"),
    ("h", "H"),
    ("j", "J"),
    ("k", "K"),
    ("db", "dB"),
    ("percent", "%"),
];

/// Name endings of quantities without a unit.
const DIMENSIONLESS: &[&str] = &["fraction", "ratio"];

/// The tool's own figure columns whose names are abbreviations, in words (a name here is
/// matched after its unit is taken off).
const WORDS: &[(&str, &str)] = &[
    ("rms", "RMS pointing error"),
    ("peak", "peak pointing error"),
    ("p95", "95th percentile pointing error"),
    ("within_target", "share within the target"),
    ("initial", "initial transmission error"),
    ("reversal", "reversal backlash"),
    ("first_reversal", "first reversal backlash"),
    ("rms_error", "RMS transmission error"),
    ("peak_error", "peak transmission error"),
    ("peak_to_peak_error", "peak-to-peak transmission error"),
];

/// Whole column names that read as a unit but are not one (`ms`: the sensitivity peak).
const WHOLE: &[(&str, &str, &str)] = &[("ms", "sensitivity peak Ms", "1")];

fn unit_word(token: &str) -> Option<&'static str> {
    UNITS.iter().find(|(t, _)| *t == token).map(|(_, u)| *u)
}

/// Unit words joined as a product; an angle followed by seconds is a rate (`rad_s`:
/// rad/s, the project's spelling of an angular speed).
fn product(tokens: &[&str]) -> String {
    let mut out = String::new();
    for (i, t) in tokens.iter().enumerate() {
        let word = unit_word(t).unwrap_or(t);
        let rate = *t == "s" && i > 0 && matches!(tokens[i - 1], "rad" | "mrad" | "urad" | "deg");
        if rate {
            out.push_str("/s");
        } else if *t == "sqrt" {
            out.push_str(if out.is_empty() { "" } else { " " });
            out.push_str("sqrt(");
        } else {
            let after_sqrt = i > 0 && tokens[i - 1] == "sqrt";
            if !out.is_empty() && !after_sqrt {
                out.push(' ');
            }
            out.push_str(word);
            if after_sqrt {
                out.push(')');
            }
        }
    }
    out
}

/// A column's words and the unit its name ends in (`None` when it names none): the unit
/// is the longest tail of unit words (`nm_s_per_rad`: N m s/rad, `rad_per_nm`: rad/(N m),
/// `per_s`: 1/s), leaving at least one word of name before it.
pub fn column_words(column: &str) -> (String, Option<String>) {
    if let Some((_, words, unit)) = WHOLE.iter().find(|(c, _, _)| *c == column) {
        return (words.to_string(), Some(unit.to_string()));
    }
    let tokens: Vec<&str> = column.split('_').collect();
    let is_unit = |t: &str| unit_word(t).is_some() || t == "per" || t == "sqrt";
    // Where the unit starts: the first of the trailing unit words, one word kept as name.
    let mut start = tokens.len();
    while start > 1 && is_unit(tokens[start - 1]) {
        start -= 1;
    }
    // A tail of only `per` or `sqrt` is no unit.
    while start < tokens.len() && !tokens[start..].iter().any(|t| unit_word(t).is_some()) {
        start += 1;
    }
    // A tail must not begin or end with a joining word (`..._per`): give those back.
    while start < tokens.len() && tokens[start] == "sqrt" {
        start += 1;
    }
    let (name, tail) = tokens.split_at(start);
    let name = name.join("_");
    let unit = if tail.is_empty() || tail.last().is_some_and(|t| *t == "per" || *t == "sqrt") {
        None
    } else {
        match tail.iter().position(|t| *t == "per") {
            Some(p) => {
                let over = product(&tail[p + 1..]);
                let over = if over.contains(' ') && !over.starts_with("sqrt") {
                    format!("({over})")
                } else {
                    over
                };
                let num = product(&tail[..p]);
                Some(format!(
                    "{}/{over}",
                    if num.is_empty() { "1" } else { &num }
                ))
            }
            None => Some(product(tail)),
        }
    };
    let (name, unit) = match unit {
        Some(u) => (name, Some(u)),
        None => match DIMENSIONLESS.iter().find_map(|d| {
            column
                .strip_suffix(d)
                .and_then(|n| n.strip_suffix('_'))
                .filter(|n| !n.is_empty())
        }) {
            Some(n) => (n.to_string(), Some("1".to_string())),
            None => (column.to_string(), None),
        },
    };
    let words = WORDS
        .iter()
        .find(|(n, _)| *n == name)
        .map_or_else(|| name.replace('_', " "), |(_, w)| w.to_string());
    (words, unit)
}

/// An axis description for a column: its words with the unit in square brackets
/// (`preload [N]`), or the words alone when the name carries no unit.
pub fn column_label(column: &str) -> String {
    match column_words(column) {
        (words, Some(unit)) => format!("{words} [{unit}]"),
        (words, None) => words,
    }
}

/// A column's value in words with its unit (`preload = 180 N`), for a legend.
pub fn column_value(column: &str, value: f64) -> String {
    // In full, as the table holds it: neighbouring swept values must not round alike.
    let v = value.to_string();
    match column_words(column) {
        (words, Some(unit)) if unit == "1" => format!("{words} = {v}"),
        (words, Some(unit)) => format!("{words} = {v} {unit}"),
        (words, None) => format!("{words} = {v}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_column_is_labelled_with_the_unit_its_name_ends_in() {
        for (column, label) in [
            ("preload_n", "preload [N]"),
            ("load_nm", "load [N m]"),
            ("reversal_mrad", "reversal backlash [mrad]"),
            ("drum_wrap_rad", "drum wrap [rad]"),
            ("rate_hz", "rate [Hz]"),
            ("duration_s", "duration [s]"),
            ("drum_radius_m", "drum radius [m]"),
            ("current_limit_a", "current limit [A]"),
            ("phase_margin_deg", "phase margin [deg]"),
            ("gain_margin_up_db", "gain margin up [dB]"),
            ("tension_upper_n", "tension upper [N]"),
            ("memory_rms_mrad", "memory rms [mrad]"),
            ("rms_mrad", "RMS pointing error [mrad]"),
            ("inertia_kg_m2", "inertia [kg m^2]"),
            ("viscous_nm_s_per_rad", "viscous [N m s/rad]"),
            ("coulomb_smoothing_rad_s", "coulomb smoothing [rad/s]"),
            ("load_compliance_rad_per_nm", "load compliance [rad/(N m)]"),
            ("torque_constant_nm_per_a", "torque constant [N m/A]"),
            ("relaxation_per_s", "relaxation [1/s]"),
            (
                "noise_density_rad_s_per_sqrt_hz",
                "noise density [rad/s/sqrt(Hz)]",
            ),
            ("distortion_percent", "distortion [%]"),
            ("within_target_fraction", "share within the target [1]"),
            ("ms", "sensitivity peak Ms [1]"),
        ] {
            assert_eq!(column_label(column), label, "{column}");
        }
    }

    /// A name that is only a unit word, or has no unit word at its end, stays a name.
    #[test]
    fn a_name_without_a_unit_keeps_its_words() {
        assert_eq!(column_label("s"), "s");
        assert_eq!(column_label("kp"), "kp");
        assert_eq!(column_label("friction_coefficient"), "friction coefficient");
        assert_eq!(column_label("steps_per"), "steps per");
        assert_eq!(column_words("x_sqrt"), ("x sqrt".to_string(), None));
    }

    #[test]
    fn a_value_is_written_with_its_unit() {
        assert_eq!(column_value("preload_n", 180.0), "preload = 180 N");
        assert_eq!(column_value("load_nm", 0.72), "load = 0.72 N m");
        assert_eq!(
            column_value("friction_coefficient", 0.2),
            "friction coefficient = 0.2"
        );
    }
}
