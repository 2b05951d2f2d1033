//! Studies built on the physics: quasi-static prescribed motion and the backlash protocol.

pub mod answers;
pub mod quasi_static;
