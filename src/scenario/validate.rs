//! Ranges and cross-checks of a whole scenario, with the key and what is allowed.

use super::*;

impl Scenario {
    /// Ranges and cross-checks; `source_name` is used in messages.
    pub fn validate(&self, source_name: &str) -> Result<(), ScenarioError> {
        let bad = |key: &str, msg: String| ScenarioError::invalid(source_name, key, msg);
        if let Some(name) = &self.name {
            if name.is_empty()
                || !name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.')
                || name.starts_with('.')
            {
                return Err(bad(
                    "name",
                    format!("{name:?} must be a non-empty folder name of letters, digits, '_', '-' or '.'"),
                ));
            }
            if name.len() > super::MAX_NAME_CHARS {
                return Err(bad(
                    "name",
                    format!(
                        "\"{}...\" is {} characters long; a results folder is named after it, so at most {} are allowed",
                        &name[..24],
                        name.len(),
                        super::MAX_NAME_CHARS
                    ),
                ));
            }
        }
        self.drive.validate().map_err(|e| {
            let key = match &e {
                crate::physics::drive::DriveParamError::OutOfRange { key, .. } => {
                    format!("drive.{key}")
                }
                crate::physics::drive::DriveParamError::NoFreeSpan { .. } => {
                    "drive.center_distance_m".to_string()
                }
            };
            let full = e.to_string();
            let message = full
                .strip_prefix(&format!("{key} = "))
                .unwrap_or(&full)
                .to_string();
            bad(&key, message)
        })?;
        self.load
            .validate()
            .map_err(|(key, msg)| bad(&format!("load.{key}"), msg))?;
        // Every section present is checked, used by the study or not: a bad value in the
        // file is a mistake either way.
        match self.study {
            Study::QuasiStatic if self.quasi_static.is_none() => {
                return Err(bad(
                    "quasi_static",
                    "study = \"quasi_static\" needs a [quasi_static] section with duration_s and [quasi_static.motion]".into(),
                ));
            }
            Study::Backlash if self.backlash.is_none() => {
                return Err(bad(
                    "backlash",
                    "study = \"backlash\" needs a [backlash] section with load_nm".into(),
                ));
            }
            Study::ClosedLoop if self.closed_loop.is_none() => {
                return Err(bad(
                    "closed_loop",
                    "study = \"closed_loop\" needs a [closed_loop] section with duration_s, [closed_loop.reference] and [closed_loop.controller]".into(),
                ));
            }
            _ => {}
        }
        if let Some(qs) = &self.quasi_static {
            if !(qs.duration_s.is_finite() && qs.duration_s > 0.0 && qs.duration_s <= 1e6) {
                return Err(bad(
                    "quasi_static.duration_s",
                    format!("{} must be in (0, 1e6] s", crate::number(qs.duration_s)),
                ));
            }
            if !(qs.sample_rate_hz.is_finite() && qs.sample_rate_hz > 0.0) {
                return Err(bad(
                    "quasi_static.sample_rate_hz",
                    format!(
                        "{} must be a finite rate > 0 Hz",
                        crate::number(qs.sample_rate_hz)
                    ),
                ));
            }
            let samples = qs.duration_s * qs.sample_rate_hz;
            if !(samples.is_finite() && samples <= MAX_QS_SAMPLES) {
                return Err(bad(
                    "quasi_static.sample_rate_hz",
                    format!(
                        "{} Hz over duration_s = {} s is {samples:.3e} samples, too many (at most {MAX_QS_SAMPLES:.0e}); lower the rate or the duration",
                        crate::number(qs.sample_rate_hz), crate::number(qs.duration_s)),
                ));
            }
            if qs.models.is_empty() {
                return Err(bad(
                    "quasi_static.models",
                    "list at least one of \"memory\", \"memoryless\"".into(),
                ));
            }
            qs.motion
                .validate()
                .map_err(|m| bad("quasi_static.motion", m))?;
            let resolve = |key: &str, what: &str, f: f64| {
                if f * SAMPLES_PER_PERIOD > qs.sample_rate_hz {
                    Err(bad(
                        key,
                        format!(
                            "{what} = {} Hz is too fast for sample_rate_hz = {}: use at least {SAMPLES_PER_PERIOD} samples per period (sample_rate_hz >= {}) or a slower signal", crate::number(f), crate::number(qs.sample_rate_hz), crate::number(f * SAMPLES_PER_PERIOD)
                        ),
                    ))
                } else {
                    Ok(())
                }
            };
            resolve(
                "quasi_static.motion",
                "the motion's frequency_hz (or 1/period_s)",
                qs.motion.fastest_frequency_hz(),
            )?;
            if self.load.sine_nm != 0.0 {
                resolve(
                    "load.sine_frequency_hz",
                    "sine_frequency_hz",
                    self.load.sine_frequency_hz,
                )?;
            }
            if let Some(t) = qs
                .profile_times_s
                .iter()
                .find(|t| !(t.is_finite() && **t >= 0.0 && **t <= qs.duration_s))
            {
                return Err(bad(
                    "quasi_static.profile_times_s",
                    format!(
                        "{} must lie within [0, duration_s = {}]",
                        crate::number(*t),
                        crate::number(qs.duration_s)
                    ),
                ));
            }
        }
        if let Some(b) = &self.backlash {
            if !(b.load_nm.is_finite()
                && b.load_nm > 0.0
                && b.load_nm <= crate::physics::load::MAX_TORQUE_NM)
            {
                return Err(bad(
                    "backlash.load_nm",
                    format!(
                        "{} must be a torque > 0 and at most 1e6 N m",
                        crate::number(b.load_nm)
                    ),
                ));
            }
        }
        if let Some(cl) = &self.closed_loop {
            cl.validate(&self.drive)
                .map_err(|(key, msg)| bad(&key, msg))?;
        }
        if let Some(id) = &self.identify {
            id.validate()
                .map_err(|(key, msg)| bad(&format!("identify.{key}"), msg))?;
        }
        if let Some(fx) = &self.effects {
            fx.validate()
                .map_err(|(key, msg)| bad(&format!("effects.{key}"), msg))?;
        }
        if let Some(sweep) = &self.sweep {
            crate::sweep::validate_spec(sweep).map_err(|(key, msg)| bad(&key, msg))?;
            self.validate_sweep_values(sweep, source_name)?;
        }
        Ok(())
    }

    /// Every value a sweep gives a key must make a valid scenario on its own (combinations
    /// are checked again before a sweep runs).
    fn validate_sweep_values(
        &self,
        sweep: &SweepSpec,
        source_name: &str,
    ) -> Result<(), ScenarioError> {
        let mut base = self.to_table();
        base.remove("sweep");
        for (i, p) in sweep.parameters.iter().enumerate() {
            let path: Vec<String> = p.key.split('.').map(str::to_string).collect();
            for (j, value) in p.values.iter().enumerate() {
                let key = format!("sweep.parameters[{i}].values[{j}]");
                let mut table = base.clone();
                let shown = format!("{} = {value}", p.key);
                set_path(&mut table, &path, value.clone()).map_err(|m| {
                    ScenarioError::invalid(source_name, &key, format!("{shown}: {m}"))
                })?;
                let case = Scenario::from_table(table, source_name, self.name()).map_err(|e| {
                    let why = match e {
                        ScenarioError::Invalid { key, message, .. }
                            if key != "scenario" && key != p.key =>
                        {
                            format!("{key}: {message}")
                        }
                        ScenarioError::Invalid { message, .. } => message,
                        other => other.to_string(),
                    };
                    ScenarioError::invalid(source_name, &key, format!("{shown}: {why}"))
                });
                case?;
            }
        }
        Ok(())
    }
}
