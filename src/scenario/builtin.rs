//! Scenarios compiled into the binary, usable by name from any directory.

/// Scenarios compiled into the binary, by name.
pub const BUILTIN: &[(&str, &str)] = &[
    (
        "eots_tracking",
        include_str!("../../scenarios/eots_tracking.toml"),
    ),
    (
        "eots_mismatch",
        include_str!("../../scenarios/eots_mismatch.toml"),
    ),
    (
        "eots_runout",
        include_str!("../../scenarios/eots_runout.toml"),
    ),
    ("eots_scan", include_str!("../../scenarios/eots_scan.toml")),
    (
        "gimbal_stabilized",
        include_str!("../../scenarios/gimbal_stabilized.toml"),
    ),
    (
        "step_stare",
        include_str!("../../scenarios/step_stare.toml"),
    ),
    (
        "gimbal_ident",
        include_str!("../../scenarios/gimbal_ident.toml"),
    ),
    (
        "davinci_tool4",
        include_str!("../../scenarios/davinci_tool4.toml"),
    ),
    (
        "davinci_tool4_loop",
        include_str!("../../scenarios/davinci_tool4_loop.toml"),
    ),
    (
        "paper_bench",
        include_str!("../../scenarios/paper_bench.toml"),
    ),
    (
        "paper_fig11",
        include_str!("../../scenarios/paper_fig11.toml"),
    ),
    (
        "eots_tolerance",
        include_str!("../../scenarios/eots_tolerance.toml"),
    ),
    (
        "paper_tension",
        include_str!("../../scenarios/paper_tension.toml"),
    ),
    (
        "memory_vs_memoryless",
        include_str!("../../scenarios/memory_vs_memoryless.toml"),
    ),
];

/// The scenario `cable-servo run` uses when given none.
pub const DEFAULT_SCENARIO: &str = "eots_tracking";

/// Text of a built-in scenario.
pub fn builtin(name: &str) -> Option<&'static str> {
    BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}
