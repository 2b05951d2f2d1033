//! Studies built on the physics: quasi-static prescribed motion, the backlash protocol and
//! the design answers they give. Computation layer: imports only physics and signal.

pub mod answers;
pub mod quasi_static;
