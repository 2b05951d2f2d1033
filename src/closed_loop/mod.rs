//! Closed-loop gimbal axis: torque motor, hysteretic cable drive and output drum under a
//! sampled PID loop with feedforward and backlash compensation.
//! Computation layer: takes a [`ClosedLoopSetup`], imports only physics, signal, metrics.
//!
//! The pieces are readable alone: [`params`] (scenario structs and their validation),
//! [`plant`] (the continuous-time equations and the brake's stick/slip logic),
//! [`controller`] (the discrete-time law and the compensator copy of the cable),
//! [`sim`] (the sample-and-hold loop that composes them). Files and figures of a run are
//! written at the edge, by `report::closed_loop`.

pub mod base;
pub mod controller;
pub mod filters;
pub mod law;
pub mod mode;
pub mod params;
pub mod period;
pub mod plant;
pub mod probe;
pub mod reference;
pub mod requirements;
pub mod sim;

pub use params::{
    Amplifier, CableModel, ClosedLoopParams, CompensationMode, ControllerParams,
    DisturbanceObserverParams, DriveOverride, Feedback, GyroParams, MotorParams, OutputParams,
    RateLoopParams, RateSource, SensorParams, StartState,
};
pub use reference::{ReferenceCache, SampledReference};
pub use requirements::Requirements;
pub use sim::{
    estimate_work, run_closed_loop, run_closed_loop_metrics, run_closed_loop_metrics_shared,
    run_closed_loop_shared, run_closed_loop_then, ClosedLoopError, ClosedLoopResult,
    ClosedLoopSetup, ClosedLoopSource, CommandSaturation, Completion, Injection, InjectionSite,
    Instability, ModeResult, RunOptions, SolverStats, StopKind, TimeSeries, WorkEstimate,
};
