//! Video2Track BV onboard runtime.
