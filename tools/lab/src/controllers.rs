//! The onboard algorithms as BV controllers of the simulated proving ground: [`RegulatedBv`] (the
//! Stackelberg regulator with pure pursuit, what the experiments run in process) and [`TrackedBv`]
//! (the PID + Stanley tracker following a reference, what the tracking measurements run).

mod cloud;
mod regulated;
mod tracked;

pub use cloud::{
    CloudBvError, CloudLink, CloudLinkStats, CloudRegulatedBv, CloudRegulator, PLAN_TIMEOUT_S, SimulatedNetwork,
    VUT_ID, clock_ms,
};
pub use regulated::{LoggedDecision, RegulatedBv, RegulatedBvError};
pub use tracked::TrackedBv;
