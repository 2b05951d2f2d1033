//! The plant as an FMI 2.0 Co-Simulation FMU: motor, cable drive (memory, memoryless or
//! linear), output drum, loads and encoders, stepped by a host's master algorithm.
//!
//! An adapter at the top of the crate, like the CLI: it reads a scenario for its defaults
//! and drives [`crate::closed_loop`]'s plant through its period functions; the plant knows
//! nothing of FMI.
//!
//! - [`variables`]: the table of FMI variables (value references, names, units, ranges),
//!   read by the C functions and by the modelDescription writer alike;
//! - [`instance`]: one instance in safe Rust: FMI state machine, parameters, `do_step`;
//! - [`ffi`]: the `fmi2*` C functions the shared library exports (panics caught there);
//! - [`export`]: `cable-servo export-fmu`: modelDescription.xml, documentation and the zip.

pub mod export;
pub mod ffi;
pub mod instance;
#[cfg(test)]
mod tests;
pub mod variables;
mod zip;

/// `modelIdentifier` of the FMU: the name of the shared library in `binaries/linux64/`.
pub const MODEL_IDENTIFIER: &str = "cable_servo";

/// Name of the scenario file inside the FMU's `resources/` folder.
pub const SCENARIO_RESOURCE: &str = "scenario.toml";

/// GUID of an FMU built from scenario text `scenario_toml`: two FNV-1a hashes of the
/// program version and the text, written as a UUID. The shared library recomputes it from
/// the scenario in its resources, so a modelDescription and resources that do not belong
/// together (or a library of another version) are refused at instantiation.
pub fn guid(scenario_toml: &str) -> String {
    let hash = |seed: u64| {
        let mut h = seed;
        for b in env!("CARGO_PKG_VERSION")
            .bytes()
            .chain([0u8])
            .chain(scenario_toml.bytes())
        {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        h
    };
    let a = hash(0xcbf2_9ce4_8422_2325);
    let b = hash(0x6c62_272e_07bb_0142);
    format!(
        "{{{:08x}-{:04x}-{:04x}-{:04x}-{:012x}}}",
        a >> 32,
        (a >> 16) & 0xffff,
        a & 0xffff,
        b >> 48,
        b & 0xffff_ffff_ffff
    )
}
