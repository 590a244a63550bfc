//! The onboard algorithms as BV controllers of the simulated proving ground: [`RegulatedBv`] (the
//! Stackelberg regulator with pure pursuit, what the experiments run in process) and [`TrackedBv`]
//! (the PID + Stanley tracker following a reference, what the tracking measurements run).

mod regulated;
mod tracked;

pub use regulated::RegulatedBv;
pub use tracked::TrackedBv;
