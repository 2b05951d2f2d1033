//! Closed-loop gimbal axis (placeholder until the loop lands).

use serde::{Deserialize, Serialize};

/// Closed-loop configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ClosedLoopParams {}
