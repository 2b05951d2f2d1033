//! The compensation modes a loop is simulated in, apart from the parameters so that the
//! requirements can name one without importing them.

use serde::{Deserialize, Serialize};

use crate::physics::HysteresisModel;

/// Which backlash compensation the controller runs. One simulation per listed mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CompensationMode {
    /// No compensation: motor reference `ic * r_out`.
    None,
    /// Compensator copy of the cable without memory (Lu and Fan style).
    Memoryless,
    /// Compensator copy of the cable with capstan memory.
    Memory,
}

impl CompensationMode {
    /// Every mode, for readers that recognise the columns a mode names in a table.
    pub const ALL: [CompensationMode; 3] = [
        CompensationMode::None,
        CompensationMode::Memoryless,
        CompensationMode::Memory,
    ];

    /// Name used in files (`none`, `memoryless`, `memory`).
    pub fn name(self) -> &'static str {
        match self {
            CompensationMode::None => "none",
            CompensationMode::Memoryless => "memoryless",
            CompensationMode::Memory => "memory",
        }
    }

    /// History model of the compensator copy, if any.
    pub fn model(self) -> Option<HysteresisModel> {
        match self {
            CompensationMode::None => None,
            CompensationMode::Memoryless => Some(HysteresisModel::Memoryless),
            CompensationMode::Memory => Some(HysteresisModel::Memory),
        }
    }
}
