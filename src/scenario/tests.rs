//! Parsing, messages and validation of scenario files.

use super::*;

#[test]
fn builtins_parse_and_validate() {
    for (name, text) in BUILTIN {
        let s = Scenario::from_toml(text, name, name, &[]);
        assert!(s.is_ok(), "{name}: {:?}", s.err());
    }
}

#[test]
fn unknown_key_suggests_the_closest() {
    let text = builtin("paper_bench")
        .unwrap()
        .replace("preload_n", "prelod_n");
    let err = Scenario::from_toml(&text, "x.toml", "x", &[])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("prelod_n") && err.contains("did you mean `preload_n`"),
        "{err}"
    );
    assert!(err.starts_with("x.toml:"), "{err}");
}

#[test]
fn type_error_names_line() {
    let text = builtin("paper_bench")
        .unwrap()
        .replace("preload_n = 100.0", "preload_n = \"lots\"");
    let line = text.lines().position(|l| l.contains("\"lots\"")).unwrap() + 1;
    let err = Scenario::from_toml(&text, "x.toml", "x", &[])
        .unwrap_err()
        .to_string();
    assert!(err.starts_with(&format!("x.toml:{line}:")), "{err}");
}

#[test]
fn overrides_apply_and_validate() {
    let text = builtin("paper_bench").unwrap();
    let s = Scenario::from_toml(
        text,
        "x",
        "x",
        &["drive.preload_n=70".into(), "drive.routing=open".into()],
    )
    .unwrap();
    assert_eq!(s.drive.preload_n, 70.0);
    assert_eq!(s.drive.routing, crate::physics::Routing::Open);
    let err = Scenario::from_toml(text, "x", "x", &["drive.prelod_n=70".into()])
        .unwrap_err()
        .to_string();
    assert!(err.contains("did you mean `preload_n`"), "{err}");
    let err = Scenario::from_toml(text, "x", "x", &["drive.preload_n=-3".into()])
        .unwrap_err()
        .to_string();
    assert!(err.contains("drive.preload_n"), "{err}");
    let err = Scenario::from_toml(text, "x", "x", &["drive.friction_coefficient=1.5".into()])
        .unwrap_err()
        .to_string();
    assert!(err.contains("(0, 1]"), "{err}");
}
#[test]
fn shortened_spellings_get_a_suggestion() {
    let m = with_suggestion("unknown variant `figure8`, expected `figure_eight` or `open`");
    assert!(m.ends_with("did you mean `figure_eight`?"), "{m}");
    let m = with_suggestion("unknown variant `diagonal`, expected `figure_eight` or `open`");
    assert!(!m.contains("did you mean"), "{m}");
}

#[test]
fn type_errors_in_tagged_sections_name_the_key_and_its_line() {
    let text = builtin("paper_bench")
        .unwrap()
        .replace("amplitude_rad = 0.1", "amplitude_rad = \"big\"");
    let line = text.lines().position(|l| l.contains("\"big\"")).unwrap() + 1;
    let err = Scenario::from_toml(&text, "x.toml", "x", &[])
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with(&format!(
            "x.toml:{line}:1: quasi_static.motion.amplitude_rad: invalid type"
        )),
        "{err}"
    );
    assert!(err.contains("expected a number"), "{err}");
}

#[test]
fn a_negative_count_asks_for_a_whole_number() {
    let err = Scenario::load("gimbal_ident", &["identify.max_effects=-1".into()])
        .map(|_| "accepted")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("identify.max_effects") && err.contains("a whole number >= 0"),
        "{err}"
    );
    assert!(!err.contains("usize"), "{err}");
}

#[test]
fn sweep_values_are_checked_one_by_one() {
    let text = builtin("paper_fig11")
        .unwrap()
        .replace("values = [10.0,", "values = [-10.0,");
    let err = Scenario::from_toml(&text, "x.toml", "x", &[])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("sweep.parameters[0].values[0]: drive.preload_n = -10.0"),
        "{err}"
    );
}

#[test]
fn sections_the_study_does_not_use_are_checked_too() {
    let text = format!(
        "{}\n[backlash]\nload_nm = -1.0\n",
        builtin("paper_bench").unwrap()
    );
    let err = Scenario::from_toml(&text, "x.toml", "x", &[])
        .unwrap_err()
        .to_string();
    assert!(err.contains("backlash.load_nm: -1"), "{err}");
}

#[test]
fn messages_stay_on_one_line() {
    let err = Scenario::from_toml(
        builtin("paper_bench").unwrap(),
        "x",
        "x",
        &["name=\"\"\"a\nb\"\"\"".into()],
    )
    .unwrap_err()
    .to_string();
    assert!(!err.contains('\n'), "{err}");
}

#[test]
fn an_unknown_name_lists_the_builtins_and_suggests_the_nearest() {
    let err = Scenario::load("eots_trackin", &[]).unwrap_err().to_string();
    assert!(err.contains("did you mean eots_tracking?"), "{err}");
    assert!(err.contains("paper_bench"), "{err}");
    let err = Scenario::load("no/such/thing.toml", &[])
        .unwrap_err()
        .to_string();
    assert!(!err.contains("did you mean"), "{err}");
    assert!(err.contains("eots_tracking"), "{err}");
}

#[test]
fn a_new_kind_replaces_the_old_kinds_keys_in_any_order() {
    let step = |sets: &[&str]| {
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        Scenario::load("eots_tracking", &sets)
    };
    // The new kind's keys before or after the switch.
    for sets in [
        &[
            "closed_loop.reference.kind=\"step\"",
            "closed_loop.reference.amplitude_rad=0.002",
        ][..],
        &[
            "closed_loop.reference.amplitude_rad=0.002",
            "closed_loop.reference.kind=\"step\"",
        ][..],
    ] {
        let s = step(sets).unwrap_or_else(|e| panic!("{sets:?}: {e}"));
        let r = &s.closed_loop.as_ref().unwrap().reference;
        assert!(
            matches!(r, crate::signal::Signal::Step { amplitude_rad, .. } if *amplitude_rad == 0.002),
            "{r:?}"
        );
    }
    // A key the new kind needs and was not given: the message says what was dropped and how.
    let err = step(&["closed_loop.reference.kind=\"ramp\""])
        .unwrap_err()
        .to_string();
    assert!(err.contains("rate_rad_s"), "{err}");
    assert!(
        err.contains("replaced the old kind's keys (amplitude_rad, frequency_hz)"),
        "{err}"
    );
    // Setting the same kind keeps the keys.
    assert!(step(&["closed_loop.reference.kind=\"sine\""]).is_ok());
}

#[test]
fn a_name_too_long_for_a_folder_is_refused_with_its_limit() {
    let long = "a".repeat(300);
    let text = builtin("paper_bench")
        .unwrap()
        .replace("name = \"paper_bench\"", &format!("name = \"{long}\""));
    let err = Scenario::from_toml(&text, "x.toml", "x", &[])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("name") && err.contains("300 characters") && err.contains("at most 100"),
        "{err}"
    );
    assert!(err.len() < 300, "{err}");
    let fits = builtin("paper_bench").unwrap().replace(
        "name = \"paper_bench\"",
        &format!("name = \"{}\"", "a".repeat(super::MAX_NAME_CHARS)),
    );
    assert!(Scenario::from_toml(&fits, "x.toml", "x", &[]).is_ok());
}

#[test]
fn a_control_rate_that_is_no_rate_is_named_as_such() {
    for rate in ["-1", "0"] {
        let set = [format!("closed_loop.controller.sample_rate_hz={rate}")];
        let err = Scenario::from_toml(
            builtin("eots_tracking").unwrap(),
            "eots_tracking",
            "eots_tracking",
            &set,
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("controller.sample_rate_hz")
                && err.contains("> 0")
                && !err.contains("Nyquist"),
            "{err}"
        );
    }
}
