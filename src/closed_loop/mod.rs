//! Closed-loop gimbal axis: torque motor, hysteretic cable drive and output drum under a
//! sampled PID loop with feedforward and backlash compensation.
//!
//! The pieces are readable alone: [`params`] (scenario structs and their validation),
//! [`plant`] (the continuous-time equations and the brake's stick/slip logic),
//! [`controller`] (the discrete-time law and the compensator copy of the cable),
//! [`sim`] (the sample-and-hold loop that composes them) and [`report`] (files at the edge).

pub mod controller;
pub mod params;
pub mod period;
pub mod plant;
pub mod report;
pub mod sim;

pub use params::{
    Amplifier, CableModel, ClosedLoopParams, CompensationMode, ControllerParams, DriveOverride,
    Feedback, MotorParams, OutputParams, SensorParams,
};
pub use report::{closed_loop_charts, format_table, plot_closed_loop, write_closed_loop_outputs};
pub use sim::{
    run_closed_loop, run_closed_loop_metrics, ClosedLoopError, ClosedLoopResult, Completion,
    ModeResult, RunOptions, SolverStats, TimeSeries,
};
