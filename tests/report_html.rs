//! `report.html` of every results directory: self-contained (no URL, every figure inline),
//! its verdict numbers those of `summary.json`, and, where a headless Chromium is
//! installed, rendered without a console error, a broken image or any request beyond the
//! file itself (driven over the DevTools protocol on `--remote-debugging-pipe`).

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use serde_json::{json, Value};

/// A command of the CLI with short settings, the verdict its page must show and whether
/// its record carries the verdict's numbers.
struct Case {
    name: &'static str,
    args: Vec<String>,
    /// `data-verdict` of the page: `pass`, `fail`, `stop` or `none`.
    verdict: &'static str,
    /// Files the command needs beside it (a bench log), made before it runs.
    setup: Option<fn(&Path)>,
}

fn strings(a: &[&str]) -> Vec<String> {
    a.iter().map(|s| s.to_string()).collect()
}

fn cases() -> Vec<Case> {
    let short = ["--set", "closed_loop.duration_s=3"];
    vec![
        Case {
            name: "run",
            args: strings(&[&["run"][..], &short].concat()),
            verdict: "pass",
            setup: None,
        },
        Case {
            name: "run_stopped",
            args: strings(&[&["run", "--set", "drive.preload_n=1.5"][..], &short].concat()),
            verdict: "stop",
            setup: None,
        },
        Case {
            name: "backlash",
            args: strings(&["run", "paper_fig11"]),
            verdict: "none",
            setup: None,
        },
        Case {
            name: "sweep",
            args: strings(&[
                "sweep",
                "eots_tracking",
                "--vary",
                "drive.preload_n=1.5,60",
                "--set",
                "closed_loop.modes=[\"memory\"]",
                "--set",
                "closed_loop.duration_s=0.6",
                "--set",
                "closed_loop.metrics_start_s=0.1",
            ]),
            verdict: "fail",
            setup: None,
        },
        Case {
            name: "compare",
            args: strings(
                &[
                    &[
                        "compare",
                        "eots_tracking",
                        "--design",
                        "soft:closed_loop.controller.kp=1",
                        "--design",
                        "shipped:drive.preload_n=100",
                    ][..],
                    &short,
                ]
                .concat(),
            ),
            verdict: "fail",
            setup: None,
        },
        Case {
            name: "margins",
            args: strings(&[&["margins"][..], &short].concat()),
            verdict: "pass",
            setup: None,
        },
        Case {
            name: "freqresp",
            args: strings(&[
                "freqresp",
                "--set",
                "closed_loop.cable=\"linear\"",
                "--set",
                "load.brake_nm=0",
                "--set",
                "load.brake_breakaway_nm=0",
                "--set",
                "closed_loop.duration_s=3",
                "--amplitudes",
                "0.5",
                "--frequencies",
                "5,20,40,100,300",
            ]),
            verdict: "pass",
            setup: None,
        },
        Case {
            name: "diagnose",
            args: strings(&[
                "diagnose",
                "--scenario",
                "gimbal_ident",
                "--data",
                "log.csv",
            ]),
            verdict: "none",
            setup: Some(|cwd| synth_log(cwd, "1", "log.csv")),
        },
        Case {
            name: "leave_one_out",
            args: strings(&[
                "diagnose",
                "--scenario",
                "gimbal_ident",
                "--leave-one-out",
                "--data",
                "a.csv",
                "--data",
                "b.csv",
            ]),
            verdict: "none",
            setup: Some(|cwd| {
                synth_log(cwd, "1", "a.csv");
                synth_log(cwd, "2", "b.csv");
            }),
        },
        Case {
            name: "design_tune",
            args: strings(&[&["design", "tune", "--quick"][..], &short].concat()),
            verdict: "pass",
            setup: None,
        },
    ]
}

fn cable_servo(args: &[String], cwd: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_cable-servo"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("the binary runs")
}

/// Run every case in its own directory, side by side; the results directory of each.
/// A `gimbal_ident` bench log drawn with `seed`, written to `out` in `cwd`.
fn synth_log(cwd: &Path, seed: &str, out: &str) {
    let o = cable_servo(
        &strings(&[
            "synth",
            "--scenario",
            "gimbal_ident",
            "--seed",
            seed,
            "--out",
            out,
        ]),
        cwd,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

fn run_all(root: &Path) -> Vec<(Case, PathBuf)> {
    let cases = cases();
    std::thread::scope(|s| {
        let handles: Vec<_> = cases
            .into_iter()
            .map(|case| {
                s.spawn(move || {
                    let cwd = root.join(case.name);
                    std::fs::create_dir_all(&cwd).unwrap();
                    if let Some(setup) = case.setup {
                        setup(&cwd);
                    }
                    let mut args = case.args.clone();
                    args.extend(strings(&["--out", "out"]));
                    let o = cable_servo(&args, &cwd);
                    let code = o.status.code();
                    assert!(
                        matches!(code, Some(0) | Some(4)),
                        "{}: exit {code:?}\n{}\n{}",
                        case.name,
                        String::from_utf8_lossy(&o.stdout),
                        String::from_utf8_lossy(&o.stderr)
                    );
                    let stderr = String::from_utf8_lossy(&o.stderr);
                    assert!(
                        !stderr.contains("report.html not written"),
                        "{}: {stderr}",
                        case.name
                    );
                    (case, cwd.join("out"))
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a case panicked"))
            .collect()
    })
}

/// Every `*.svg` under `dir` (hidden entries skipped), relative and `/`-separated.
fn svg_files(dir: &Path, rel: &str, out: &mut Vec<(String, PathBuf)>) {
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue;
        }
        let r = if rel.is_empty() {
            name.clone()
        } else {
            format!("{rel}/{name}")
        };
        let path = e.path();
        if path.is_dir() {
            svg_files(&path, &r, out);
        } else if name.ends_with(".svg") {
            out.push((r, path));
        }
    }
}

fn attr_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&#39;")
}

/// Values of `name="..."`/`name='...'` attributes and CSS `url(...)` in the page.
fn references(html: &str) -> Vec<String> {
    let mut out = Vec::new();
    for key in ["src=\"", "href=\"", "src='", "href='", "url("] {
        let close = match key.chars().last() {
            Some('(') => ')',
            Some(q) => q,
            None => continue,
        };
        let mut from = 0;
        while let Some(i) = html[from..].find(key) {
            let s = from + i + key.len();
            let len = html[s..].find(close).unwrap_or(0);
            out.push(
                html[s..s + len]
                    .trim()
                    .trim_matches(['"', '\''])
                    .to_string(),
            );
            from = s + len;
        }
    }
    out
}

/// The text of the cell with `class` in a table row.
fn cell<'a>(row: &'a str, class: &str) -> &'a str {
    let key = format!("class=\"num {class}\">");
    let i = row
        .find(&key)
        .unwrap_or_else(|| panic!("no {class} in {row}"))
        + key.len();
    let j = row[i..].find("</td>").unwrap_or(0);
    &row[i..i + j]
}

/// A displayed number (`&gt;= 35` is 35; the dash of a missing value is `None`).
fn shown(text: &str) -> Option<f64> {
    let last = text.split_whitespace().last()?;
    if last == "\u{2014}" {
        return None;
    }
    Some(
        last.parse()
            .unwrap_or_else(|e| panic!("{text:?} is not a number: {e}")),
    )
}

/// The page shows `value` as the console does: four significant digits.
fn same_number(page: Option<f64>, record: Option<f64>, what: &str) {
    match (page, record) {
        (None, None) => {}
        (Some(p), Some(r)) => assert!(
            (p - r).abs() <= 5e-4 * r.abs() + 1e-300,
            "{what}: page {p}, summary.json {r}"
        ),
        _ => panic!("{what}: page {page:?}, summary.json {record:?}"),
    }
}

/// Every check of a verdict record against the rows of the page's table `key`.
fn verdict_matches(html: &str, key: &str, verdict: &Value, case: &str) {
    let start = html
        .find(&format!("data-key=\"{}\"", attr_escape(key)))
        .unwrap_or_else(|| panic!("{case}: no table {key}"));
    let table = &html[start..start + html[start..].find("</table>").unwrap_or(0)];
    let checks = verdict["checks"].as_array().expect("checks");
    assert!(!checks.is_empty(), "{case}: no checks");
    for c in checks {
        let what = format!(
            "{case} {key} {} ({})",
            c["requirement"].as_str().unwrap_or(""),
            c["condition"].as_str().unwrap_or("")
        );
        let tr = format!(
            "<tr data-requirement=\"{}\" data-condition=\"{}\">",
            attr_escape(c["requirement"].as_str().unwrap_or("")),
            attr_escape(c["condition"].as_str().unwrap_or(""))
        );
        let i = table.find(&tr).unwrap_or_else(|| panic!("{what}: no row"));
        let row = &table[i..i + table[i..].find("</tr>").unwrap_or(0)];
        same_number(shown(cell(row, "measured")), c["measured"].as_f64(), &what);
        same_number(shown(cell(row, "limit")), c["limit"].as_f64(), &what);
        same_number(shown(cell(row, "margin")), c["margin"].as_f64(), &what);
        let mark = if c["passes"].as_bool() == Some(true) {
            ">ok</td>"
        } else {
            ">FAIL</td>"
        };
        assert!(row.contains(mark), "{what}: {row}");
    }
}

/// The checks every page passes without a browser; returns the figures' count.
fn static_checks(case: &Case, dir: &Path) -> usize {
    let path = dir.join("report.html");
    let html = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {}: {e}", case.name, path.display()));
    if case.name == "leave_one_out" {
        // The page shows the table the console prints, not a bare verdict.
        assert!(
            html.contains("Leave one log out") && html.contains("Extended beats base on"),
            "leave_one_out: the page lacks the table"
        );
        // As a table of the page, one row per log, not Markdown in a text block.
        let table = html
            .split("<table class=\"text-table\">")
            .nth(1)
            .and_then(|t| t.split("</table>").next())
            .expect("leave_one_out: the per-log table is an HTML table");
        assert!(table.contains("<th>log left out</th>"), "{table}");
        let logs: Vec<&str> = table
            .split("<tr><td>")
            .skip(1)
            .filter_map(|r| r.split("</td>").next())
            .collect();
        assert_eq!(logs, ["a.csv", "b.csv"], "{table}");
        assert!(
            !html.contains("|---|"),
            "leave_one_out: Markdown left in the page"
        );
    }
    for r in references(&html) {
        let lower = r.to_ascii_lowercase();
        assert!(
            !(lower.starts_with("http:") || lower.starts_with("https:") || lower.starts_with("//")),
            "{}: external reference {r}",
            case.name
        );
    }
    for tag in [
        "<img", "<script", "<link", "<iframe", "<object", "<embed", "@import",
    ] {
        assert!(!html.contains(tag), "{}: {tag} in the page", case.name);
    }
    let mut figures = Vec::new();
    svg_files(dir, "", &mut figures);
    assert_eq!(
        html.matches("<figure ").count(),
        figures.len(),
        "{}: figures {:?}",
        case.name,
        figures.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    for (rel, file) in &figures {
        assert!(
            html.contains(&format!("data-file=\"{}\"", attr_escape(rel))),
            "{}: {rel} not inlined",
            case.name
        );
        // The drawing itself is in the page: a stretch of its body, after the root tag.
        let svg = std::fs::read_to_string(file).unwrap();
        let body = &svg[svg.find("<svg").unwrap()..];
        let body = &body[body.find('>').unwrap() + 1..];
        let piece: String = body.trim_start().chars().take(300).collect();
        assert!(
            html.contains(&piece),
            "{}: {rel} body not inlined",
            case.name
        );
    }
    assert!(
        html.contains(&format!("data-verdict=\"{}\"", case.verdict)),
        "{}: verdict is not {}",
        case.name,
        case.verdict
    );
    let summary: Value = std::fs::read(dir.join("summary.json"))
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok())
        .unwrap_or(Value::Null);
    if summary["verdict"].is_object() {
        verdict_matches(&html, "verdict", &summary["verdict"], case.name);
    }
    // Every simulated mode's figures, as the console's table gives them.
    if let Some(modes) = summary["modes"].as_array() {
        let start = html
            .find("data-key=\"modes\"")
            .unwrap_or_else(|| panic!("{}: no table of the modes", case.name));
        let table = &html[start..start + html[start..].find("</table>").unwrap_or(0)];
        for m in modes {
            let name = m["name"].as_str().unwrap_or("");
            if m["completion"]["status"] != "complete" {
                // A stopped mode shows its reason, no figures.
                let tr = format!(
                    "<tr data-requirement=\"pointing_error\" data-condition=\"mode {name}\">"
                );
                assert!(table.contains(&tr), "{}: stopped mode {name}", case.name);
                continue;
            }
            for (requirement, key) in [
                ("rms_error", "rms_mrad"),
                ("peak_error", "peak_mrad"),
                ("p95_error", "p95_mrad"),
            ] {
                let what = format!("{} mode {name} {requirement}", case.name);
                let tr = format!(
                    "<tr data-requirement=\"{requirement}\" data-condition=\"mode {name}\">"
                );
                let i = table.find(&tr).unwrap_or_else(|| panic!("{what}: no row"));
                let row = &table[i..i + table[i..].find("</tr>").unwrap_or(0)];
                same_number(shown(cell(row, "measured")), m[key].as_f64(), &what);
            }
        }
    }
    for d in summary["designs"].as_array().into_iter().flatten() {
        let key = format!("design:{}", d["name"].as_str().unwrap_or(""));
        verdict_matches(&html, &key, &d["verdict"], case.name);
    }
    for a in summary["freqresp"]["amplitudes"]
        .as_array()
        .into_iter()
        .flatten()
    {
        let condition = format!(
            "amplitude {} {}",
            a["amplitude"],
            a["unit"].as_str().unwrap_or("")
        );
        for (requirement, key) in [
            ("phase_margin", "phase_margin_deg"),
            ("gain_margin_up", "gain_margin_db"),
            ("gain_margin_down", "lower_gain_margin_db"),
            ("sensitivity_peak", "ms"),
        ] {
            let tr = format!(
                "<tr data-requirement=\"{requirement}\" data-condition=\"{}\">",
                attr_escape(&condition)
            );
            let what = format!("{} {requirement} ({condition})", case.name);
            let i = html.find(&tr).unwrap_or_else(|| panic!("{what}: no row"));
            let row = &html[i..i + html[i..].find("</tr>").unwrap_or(0)];
            same_number(
                shown(cell(row, "measured")),
                a["margins"][key].as_f64(),
                &what,
            );
        }
    }
    if summary["complete"].as_bool() == Some(false) {
        assert!(html.contains("INCOMPLETE"), "{}: not marked", case.name);
    }
    assert!(!html.contains("NaN"), "{}: NaN in the page", case.name);
    figures.len()
}

/// A headless Chromium, if one is installed.
fn browser() -> Option<PathBuf> {
    ["chromium-headless-shell", "chromium"]
        .iter()
        .find_map(|name| {
            std::env::var_os("PATH").and_then(|paths| {
                std::env::split_paths(&paths)
                    .map(|p| p.join(name))
                    .find(|p| p.is_file())
            })
        })
}

/// A browser driven over the DevTools protocol on a pipe: commands are NUL-terminated
/// JSON on its fd 3, answers and events on its fd 4.
struct Cdp {
    child: Child,
    to: std::process::ChildStdin,
    from: mpsc::Receiver<Value>,
    next_id: u64,
    events: Vec<Value>,
    stderr: std::thread::JoinHandle<String>,
}

impl Cdp {
    fn start(exe: &Path, profile: &Path) -> Cdp {
        // The shell maps our pipes onto fds 3 and 4, where --remote-debugging-pipe looks.
        let mut child = Command::new("sh")
            .arg("-c")
            .arg("exec \"$0\" \"$@\" 3<&0 4>&1 </dev/null >/dev/null")
            .arg(exe)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-extensions",
                "--remote-debugging-pipe",
                "--enable-logging=stderr",
                "--v=0",
            ])
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg("about:blank")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("the browser starts");
        let to = child.stdin.take().expect("pipe");
        let out = child.stdout.take().expect("pipe");
        let err = child.stderr.take().expect("pipe");
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let mut reader = BufReader::new(out);
            let mut buf = Vec::new();
            while reader.read_until(0, &mut buf).is_ok_and(|n| n > 0) {
                if buf.last() == Some(&0) {
                    buf.pop();
                }
                if let Ok(v) = serde_json::from_slice::<Value>(&buf) {
                    if tx.send(v).is_err() {
                        break;
                    }
                }
                buf.clear();
            }
        });
        let stderr = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = BufReader::new(err).read_to_string(&mut s);
            s
        });
        Cdp {
            child,
            to,
            from: rx,
            next_id: 0,
            events: Vec::new(),
            stderr,
        }
    }

    /// Send a command (to a page session when given) and wait for its answer.
    fn call(&mut self, session: Option<&str>, method: &str, params: Value) -> Value {
        self.next_id += 1;
        let id = self.next_id;
        let mut msg = json!({ "id": id, "method": method, "params": params });
        if let Some(s) = session {
            msg["sessionId"] = json!(s);
        }
        let mut bytes = serde_json::to_vec(&msg).unwrap();
        bytes.push(0);
        self.to.write_all(&bytes).expect("the browser reads");
        self.to.flush().expect("the browser reads");
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let v = self.next_message(deadline, &format!("answer to {method}"));
            if v["id"].as_u64() == Some(id) {
                assert!(v["error"].is_null(), "{method}: {v}");
                return v["result"].clone();
            }
            self.events.push(v);
        }
    }

    /// The browser's next message, failing the test with `what` at `deadline`.
    fn next_message(&mut self, deadline: Instant, what: &str) -> Value {
        let left = deadline.saturating_duration_since(Instant::now());
        self.from
            .recv_timeout(left)
            .unwrap_or_else(|e| panic!("no {what}: {e}"))
    }

    /// Wait for an event of the session, keeping every event seen.
    fn wait_event(&mut self, session: &str, method: &str) {
        if self
            .events
            .iter()
            .any(|e| e["method"] == method && e["sessionId"] == session)
        {
            return;
        }
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let v = self.next_message(deadline, method);
            let hit = v["method"] == method && v["sessionId"] == session;
            self.events.push(v);
            if hit {
                return;
            }
        }
    }

    fn close(mut self) -> String {
        let _ = self.call(None, "Browser.close", json!({}));
        let deadline = Instant::now() + Duration::from_secs(10);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                break;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        self.stderr.join().unwrap_or_default()
    }
}

/// What the browser saw of one page.
struct Rendered {
    verdict_text: String,
    body_chars: u64,
    drawn_figures: u64,
    broken_images: u64,
    problems: Vec<String>,
}

fn render(cdp: &mut Cdp, page: &Path) -> Rendered {
    let target = cdp.call(None, "Target.createTarget", json!({ "url": "about:blank" }));
    let target_id = target["targetId"].as_str().expect("target").to_string();
    let attached = cdp.call(
        None,
        "Target.attachToTarget",
        json!({ "targetId": target_id, "flatten": true }),
    );
    let session = attached["sessionId"].as_str().expect("session").to_string();
    let s = Some(session.as_str());
    for domain in [
        "Runtime.enable",
        "Log.enable",
        "Network.enable",
        "Page.enable",
    ] {
        cdp.call(s, domain, json!({}));
    }
    let first_event = cdp.events.len();
    let url = format!("file://{}", page.display());
    cdp.call(s, "Page.navigate", json!({ "url": url }));
    cdp.wait_event(&session, "Page.loadEventFired");
    let probe = "JSON.stringify({\
        verdict: (document.getElementById('verdict') || {innerText: ''}).innerText,\
        body: document.body ? document.body.innerText.length : 0,\
        drawn: Array.from(document.querySelectorAll('figure svg')).filter(s => { const r = s.getBoundingClientRect(); return r.width > 0 && r.height > 0; }).length,\
        broken: Array.from(document.images).filter(i => !i.complete || i.naturalWidth === 0).length})";
    let r = cdp.call(
        s,
        "Runtime.evaluate",
        json!({ "expression": probe, "returnByValue": true }),
    );
    let v: Value = serde_json::from_str(r["result"]["value"].as_str().unwrap_or("{}")).unwrap();
    let mut problems = Vec::new();
    for e in &cdp.events[first_event..] {
        if e["sessionId"] != session.as_str() {
            continue;
        }
        let p = &e["params"];
        match e["method"].as_str().unwrap_or("") {
            "Runtime.consoleAPICalled"
                if matches!(p["type"].as_str(), Some("error" | "assert" | "warning")) =>
            {
                problems.push(format!("console {}: {}", p["type"], p["args"]));
            }
            "Runtime.exceptionThrown" => problems.push(format!("exception: {p}")),
            "Log.entryAdded" if p["entry"]["level"] == "error" => {
                problems.push(format!("log: {}", p["entry"]))
            }
            "Network.requestWillBeSent" => {
                let u = p["request"]["url"].as_str().unwrap_or("");
                if !u.starts_with("file:") {
                    problems.push(format!("request to {u}"));
                }
            }
            "Network.loadingFailed" => problems.push(format!("loading failed: {p}")),
            _ => {}
        }
    }
    cdp.call(None, "Target.closeTarget", json!({ "targetId": target_id }));
    Rendered {
        verdict_text: v["verdict"].as_str().unwrap_or("").to_string(),
        body_chars: v["body"].as_u64().unwrap_or(0),
        drawn_figures: v["drawn"].as_u64().unwrap_or(0),
        broken_images: v["broken"].as_u64().unwrap_or(0),
        problems,
    }
}

#[test]
fn every_results_directory_has_a_self_contained_report() {
    let started = Instant::now();
    let tmp = tempfile::tempdir().unwrap();
    let runs = run_all(tmp.path());
    let mut figures = HashMap::new();
    for (case, dir) in &runs {
        figures.insert(case.name, static_checks(case, dir));
    }
    println!(
        "static checks done at {:.1} s",
        started.elapsed().as_secs_f64()
    );
    let Some(exe) = browser() else {
        println!(
            "skipped: no headless Chromium (install the Debian package chromium-headless-shell)"
        );
        return;
    };
    let mut cdp = Cdp::start(&exe, &tmp.path().join("profile"));
    let words = [
        ("pass", "PASS"),
        ("fail", "REQUIREMENT NOT MET"),
        ("stop", "STOPPED"),
        ("none", "NOT JUDGED"),
    ];
    let mut failures = Vec::new();
    for (case, dir) in &runs {
        let page = dir
            .join("report.html")
            .canonicalize()
            .expect("the page exists");
        let r = render(&mut cdp, &page);
        let word = words
            .iter()
            .find(|w| w.0 == case.verdict)
            .map_or("", |w| w.1);
        if !r.verdict_text.contains(word) {
            failures.push(format!("{}: verdict shows {:?}", case.name, r.verdict_text));
        }
        if r.body_chars < 200 {
            failures.push(format!(
                "{}: the page renders {} characters",
                case.name, r.body_chars
            ));
        }
        if r.drawn_figures != figures[case.name] as u64 {
            failures.push(format!(
                "{}: {} of {} figures drawn",
                case.name, r.drawn_figures, figures[case.name]
            ));
        }
        if r.broken_images > 0 {
            failures.push(format!("{}: {} broken images", case.name, r.broken_images));
        }
        failures.extend(r.problems.iter().map(|p| format!("{}: {p}", case.name)));
    }
    let stderr = cdp.close();
    // Console messages also reach the browser's log; an error there is one too.
    for line in stderr.lines().filter(|l| l.contains(":CONSOLE")) {
        failures.push(format!("browser log: {line}"));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    println!(
        "{} pages rendered in a headless browser; {:.1} s in all",
        runs.len(),
        started.elapsed().as_secs_f64()
    );
}
