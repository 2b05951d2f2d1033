//! Judging a loop: its exact linear reference, margins over every crossing, the frequency
//! response measured on the simulated loop, the error budget, and the one verdict against
//! the scenario's requirements. Computation layer: reads `closed_loop`'s parameters and
//! runs its simulation; `closed_loop` knows nothing of this room.

pub mod budget;
pub mod freqresp;
pub mod linear;
pub mod linear_model;
pub mod margins;
mod resolvent;
pub mod verdict;
