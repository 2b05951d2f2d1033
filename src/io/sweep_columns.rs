//! The columns of a sweep table (`sweep.csv`) and what each cell may hold: written by the
//! case runners, checked by `merge` on every shard it reads, so a shard edited by hand or
//! damaged cannot pass junk into the merged table.

use crate::closed_loop::{CompensationMode, StopKind};
use crate::study::quasi_static::Regime;

/// The figure columns of a backlash sweep (the `+M, -M, +M` protocol).
pub const BACKLASH: [&str; 8] = [
    "initial_mrad",
    "reversal_mrad",
    "first_reversal_mrad",
    "regime",
    "anchor_reached",
    "tension_upper_n",
    "status",
    "stop",
];

/// The figure columns of a quasi-static sweep (first model of the scenario).
pub const QUASI_STATIC: [&str; 8] = [
    "peak_error_mrad",
    "peak_to_peak_error_mrad",
    "rms_error_mrad",
    "largest_jump_mrad",
    "tension_min_n",
    "tension_max_n",
    "status",
    "stop",
];

/// The figure columns of a closed-loop sweep per compensation mode, each written
/// `<mode>_<figure>`.
pub const CLOSED_LOOP_MODE: [&str; 7] = [
    "rms_mrad",
    "peak_mrad",
    "p95_mrad",
    "within_target_fraction",
    "passes_target",
    "status",
    "stop",
];

/// The closing columns of a closed-loop sweep: the case's verdict over every requirement.
pub const CLOSED_LOOP_VERDICT: [&str; 6] = [
    "passes",
    "phase_margin_deg",
    "gain_margin_up_db",
    "gain_margin_down_db",
    "ms",
    "failing",
];

/// What a cell of a sweep table may hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Content {
    /// The case number: a whole number from 0.
    Case,
    /// A swept number: finite, never blank (every case has a value for every parameter).
    NumberParameter,
    /// A swept value that is not a number (a name such as a model): any text but blank.
    TextParameter,
    /// A figure: a finite number, or blank when the case has none (it stopped, or the
    /// figure is not defined for it).
    Figure,
    /// `true` or `false`.
    Flag,
    /// How the case ended: `ok`, the stop's name or `error`.
    Status,
    /// The regime the backlash protocol reached, blank when it could not run.
    Regime,
    /// Why a case stopped or fails: free text, blank when there is nothing to say.
    Reason,
}

/// Every word a status column may hold.
pub fn status_words() -> Vec<&'static str> {
    let mut words = vec!["ok"];
    for name in StopKind::ALL
        .iter()
        .map(|k| k.name())
        .chain(Regime::ALL.iter().map(|r| r.as_str()))
    {
        if !words.contains(&name) {
            words.push(name);
        }
    }
    words.push("error");
    words
}

/// Whether `cell` reads as a finite number (as the table writes them: no blanks around).
fn finite(cell: &str) -> bool {
    cell.parse::<f64>().is_ok_and(f64::is_finite)
}

/// `a`, `b` or `c` for a message.
fn one_of(words: &[&str]) -> String {
    match words {
        [] => String::new(),
        [one] => format!("`{one}`"),
        [rest @ .., last] => format!(
            "{} or `{last}`",
            rest.iter()
                .map(|w| format!("`{w}`"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

impl Content {
    /// Whether `cell` is a value this column may hold.
    pub fn admits(self, cell: &str) -> bool {
        match self {
            Content::Case => !cell.is_empty() && cell.bytes().all(|b| b.is_ascii_digit()),
            Content::NumberParameter => finite(cell),
            Content::TextParameter => !cell.trim().is_empty(),
            Content::Figure => cell.is_empty() || finite(cell),
            Content::Flag => cell == "true" || cell == "false",
            Content::Status => status_words().contains(&cell),
            Content::Regime => cell.is_empty() || Regime::ALL.iter().any(|r| r.as_str() == cell),
            Content::Reason => true,
        }
    }

    /// What the column may hold, for a message that refuses a cell.
    pub fn allowed(self) -> String {
        match self {
            Content::Case => "a case number (a whole number from 0)".into(),
            Content::NumberParameter => {
                "a finite number (the case's value of the swept parameter)".into()
            }
            Content::TextParameter => "the case's value of the swept parameter (not blank)".into(),
            Content::Figure => {
                "a finite number, or a blank cell for a case without this figure".into()
            }
            Content::Flag => one_of(&["true", "false"]),
            Content::Status => one_of(&status_words()),
            Content::Regime => format!(
                "{}, or a blank cell for a case that could not run",
                one_of(&Regime::ALL.map(|r| r.as_str()))
            ),
            Content::Reason => "any text".into(),
        }
    }
}

/// The columns of a sweep table read from its header: what each holds, and which figures
/// each status column speaks for.
#[derive(Clone, Debug, PartialEq)]
pub struct Layout {
    /// Column names, in order, `case` first.
    pub names: Vec<String>,
    /// What each column holds; parameters are [`Content::NumberParameter`] until told
    /// otherwise by [`Layout::set_parameter_kinds`].
    pub contents: Vec<Content>,
    /// Number of parameter columns (they follow `case`).
    pub parameters: usize,
}

/// How many figure columns a closed-loop table has at the end of `names`, when they end
/// with the verdict after at least one mode's columns.
fn closed_loop_figures(names: &[String]) -> Option<usize> {
    let n = names.len();
    let verdict = CLOSED_LOOP_VERDICT.len();
    if n < verdict || names[n - verdict..] != CLOSED_LOOP_VERDICT {
        return None;
    }
    let mut end = n - verdict;
    let width = CLOSED_LOOP_MODE.len();
    // `case` stays ahead of the modes' columns.
    while end > width {
        let group = &names[end - width..end];
        let is_mode = CompensationMode::ALL.iter().any(|m| {
            group
                .iter()
                .zip(CLOSED_LOOP_MODE)
                .all(|(name, figure)| *name == format!("{}_{figure}", m.name()))
        });
        if !is_mode {
            break;
        }
        end -= width;
    }
    (end < n - verdict).then_some(n - end)
}

impl Layout {
    /// Read a header (`case`, the parameter columns, then the figures of one study).
    /// Errors name what is wrong with it.
    pub fn of_header(names: &[String]) -> Result<Layout, String> {
        if names.first().map(String::as_str) != Some("case") {
            return Err("the first column is not `case`: not a sweep table".into());
        }
        let ends_with = |figures: &[&str]| {
            names.len() > figures.len() && names[names.len() - figures.len()..] == *figures
        };
        let figures = if ends_with(&BACKLASH) {
            BACKLASH.len()
        } else if ends_with(&QUASI_STATIC) {
            QUASI_STATIC.len()
        } else if let Some(n) = closed_loop_figures(names) {
            n
        } else {
            return Err(format!(
                "the columns after the parameters are not those of a sweep this version of cable-servo writes (backlash: {}; quasi-static: {}; closed loop: <mode>_{} for each mode, then {}); a shard written by another version must be rerun",
                BACKLASH.join(","),
                QUASI_STATIC.join(","),
                CLOSED_LOOP_MODE.join(",<mode>_"),
                CLOSED_LOOP_VERDICT.join(",")
            ));
        };
        let parameters = names.len() - 1 - figures;
        let mut contents = vec![Content::Case];
        contents.extend((0..parameters).map(|_| Content::NumberParameter));
        contents.extend(names[1 + parameters..].iter().map(|name| {
            let figure = CompensationMode::ALL
                .iter()
                .find_map(|m| {
                    name.strip_prefix(m.name())
                        .and_then(|rest| rest.strip_prefix('_'))
                        .filter(|rest| CLOSED_LOOP_MODE.contains(rest))
                })
                .unwrap_or(name);
            match figure {
                "status" => Content::Status,
                "stop" | "failing" => Content::Reason,
                "regime" => Content::Regime,
                "anchor_reached" | "passes_target" | "passes" => Content::Flag,
                _ => Content::Figure,
            }
        }));
        Ok(Layout {
            names: names.to_vec(),
            contents,
            parameters,
        })
    }

    /// Mark which parameter columns hold numbers (`true`) and which names.
    pub fn set_parameter_kinds(&mut self, numeric: &[bool]) {
        for (content, &number) in self.contents[1..=self.parameters].iter_mut().zip(numeric) {
            *content = if number {
                Content::NumberParameter
            } else {
                Content::TextParameter
            };
        }
    }

    /// The first cell of a row that breaks the table's rules: `(column index, what the
    /// cell should hold)`. A row with as many cells as columns is expected.
    ///
    /// Beside each cell's own content, a case that did not finish (status other than
    /// `ok`) must have blank figures under its status (the figures of the part it ran
    /// would read as results) and name its reason.
    pub fn check_row(&self, cells: &[&str]) -> Option<(usize, String)> {
        if let Some(j) =
            (0..self.contents.len().min(cells.len())).find(|&j| !self.contents[j].admits(cells[j]))
        {
            return Some((j, format!("allowed: {}", self.contents[j].allowed())));
        }
        for (s, _) in self
            .contents
            .iter()
            .enumerate()
            .filter(|(_, c)| **c == Content::Status)
        {
            let status = cells.get(s).copied().unwrap_or_default();
            if status == "ok" {
                continue;
            }
            let prefix = self.names[s].strip_suffix("status").unwrap_or_default();
            let governed = |j: usize| j > self.parameters && self.names[j].starts_with(prefix);
            if let Some(j) = (0..cells.len()).find(|&j| {
                governed(j) && self.contents[j] == Content::Figure && !cells[j].is_empty()
            }) {
                return Some((
                    j,
                    format!(
                        "a case whose {} is `{status}` has no figures: the cell must be blank",
                        self.names[s]
                    ),
                ));
            }
            let stop = format!("{prefix}stop");
            if let Some(j) = self.names.iter().position(|n| *n == stop) {
                if cells.get(j).is_some_and(|c| c.trim().is_empty()) {
                    return Some((
                        j,
                        format!(
                            "a case whose {} is `{status}` names why: the cell must not be blank",
                            self.names[s]
                        ),
                    ));
                }
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(text: &str) -> Vec<String> {
        text.split(',').map(str::to_string).collect()
    }

    #[test]
    fn each_study_s_header_is_recognised() {
        let backlash = Layout::of_header(&names(&format!(
            "case,preload_n,load_nm,{}",
            BACKLASH.join(",")
        )))
        .unwrap();
        assert_eq!(backlash.parameters, 2);
        assert_eq!(backlash.contents[3], Content::Figure);
        assert_eq!(backlash.contents[6], Content::Regime);
        let closed = Layout::of_header(&names(&format!(
            "case,preload_n,none_{},memory_{},{}",
            CLOSED_LOOP_MODE.join(",none_"),
            CLOSED_LOOP_MODE.join(",memory_"),
            CLOSED_LOOP_VERDICT.join(",")
        )))
        .unwrap();
        assert_eq!(closed.parameters, 1);
        let at = |name: &str| closed.contents[closed.names.iter().position(|n| n == name).unwrap()];
        assert_eq!(at("none_status"), Content::Status);
        assert_eq!(at("memory_passes_target"), Content::Flag);
        assert_eq!(at("memory_stop"), Content::Reason);
        assert_eq!(at("ms"), Content::Figure);
        assert_eq!(at("failing"), Content::Reason);
        let e = Layout::of_header(&names("case,preload_n,initial_mrad")).unwrap_err();
        assert!(e.contains("another version"), "{e}");
        assert!(Layout::of_header(&names("index,initial_mrad")).is_err());
    }

    #[test]
    fn every_stop_and_regime_is_a_status_word() {
        let words = status_words();
        for k in StopKind::ALL {
            assert!(words.contains(&k.name()), "{}", k.name());
        }
        for r in Regime::ALL {
            assert!(words.contains(&r.as_str()), "{}", r.as_str());
        }
        assert!(words.contains(&"ok") && words.contains(&"error"));
    }

    #[test]
    fn junk_cells_are_refused_with_what_is_allowed() {
        let layout =
            Layout::of_header(&names(&format!("case,preload_n,{}", BACKLASH.join(",")))).unwrap();
        let row = |text: &str| -> Option<(usize, String)> {
            let cells: Vec<&str> = text.split(',').collect();
            layout.check_row(&cells)
        };
        assert_eq!(row("2,10,0.1,0.2,0.2,ok,false,11,ok,"), None);
        assert_eq!(
            row("2,10,,,,slack,false,,slack,upper span goes slack"),
            None
        );
        assert_eq!(row("2,abc,0.1,0.2,0.2,ok,false,11,ok,").unwrap().0, 1);
        assert_eq!(row("2,10,nan,0.2,0.2,ok,false,11,ok,").unwrap().0, 2);
        assert_eq!(row("2,10,0.1,inf,0.2,ok,false,11,ok,").unwrap().0, 3);
        assert_eq!(row("2,10,0.1,0.2,0.2,fine,false,11,ok,").unwrap().0, 5);
        assert_eq!(row("2,10,0.1,0.2,0.2,ok,no,11,ok,").unwrap().0, 6);
        let (j, allowed) = row("2,10,0.1,0.2,0.2,ok,false,11,done,").unwrap();
        assert_eq!(j, 8);
        assert!(
            allowed.contains("`gross_slip`") && allowed.contains("`error`"),
            "{allowed}"
        );
        // A stopped case with figures, or without its reason.
        let (j, allowed) = row("2,10,0.1,,,slack,false,,slack,upper span goes slack").unwrap();
        assert_eq!(j, 2);
        assert!(allowed.contains("has no figures"), "{allowed}");
        let (j, allowed) = row("2,10,,,,slack,false,,slack,").unwrap();
        assert_eq!(j, 9);
        assert!(allowed.contains("names why"), "{allowed}");
        assert_eq!(row("-1,10,0.1,0.2,0.2,ok,false,11,ok,").unwrap().0, 0);
    }
}
