//! Enumerations that cross the wire as `u8` codes.

/// A code outside an enumeration's range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CodeError {
    /// Which enumeration.
    pub what: &'static str,
    /// The code received.
    pub code: u8,
}

impl core::fmt::Display for CodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "unknown {} code {}", self.what, self.code)
    }
}

impl core::error::Error for CodeError {}

/// An enumeration with a one-byte wire code.
pub trait Code: Sized + Copy + 'static {
    /// Every variant, in code order.
    const ALL: &'static [Self];
    /// Name of the enumeration in error messages.
    const WHAT: &'static str;
    /// The wire code.
    fn code(self) -> u8;
    /// The variant of a wire code.
    fn from_code(code: u8) -> Result<Self, CodeError> {
        Self::ALL.iter().copied().find(|v| v.code() == code).ok_or(CodeError { what: Self::WHAT, code })
    }
}

macro_rules! wire_enum {
    ($(#[$m:meta])* $name:ident, $what:literal { $($(#[$vm:meta])* $var:ident = $code:literal),+ $(,)? }) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
        #[serde(rename_all = "snake_case")]
        pub enum $name {
            $($(#[$vm])* $var),+
        }
        impl Code for $name {
            const ALL: &'static [Self] = &[$(Self::$var),+];
            const WHAT: &'static str = $what;
            fn code(self) -> u8 {
                match self { $(Self::$var => $code),+ }
            }
        }
    };
}

wire_enum!(
    /// Who passes the conflict zone first.
    StyleCode, "style" {
        /// The BV passes first.
        Rush = 1,
        /// The VUT passes first.
        Yield = 2,
    }
);

impl From<v2t_model::Style> for StyleCode {
    fn from(s: v2t_model::Style) -> Self {
        match s {
            v2t_model::Style::Rush => Self::Rush,
            v2t_model::Style::Yield => Self::Yield,
        }
    }
}

impl From<StyleCode> for v2t_model::Style {
    fn from(s: StyleCode) -> Self {
        match s {
            StyleCode::Rush => Self::Rush,
            StyleCode::Yield => Self::Yield,
        }
    }
}

wire_enum!(
    /// Kind of conflict zone.
    ZoneKind, "zone kind" {
        /// The paths cross and separate again.
        Crossing = 1,
        /// The BV's path joins the VUT's.
        Merge = 2,
    }
);

impl From<v2t_model::metrics::ConflictKind> for ZoneKind {
    fn from(k: v2t_model::metrics::ConflictKind) -> Self {
        match k {
            v2t_model::metrics::ConflictKind::Crossing => Self::Crossing,
            v2t_model::metrics::ConflictKind::Merge => Self::Merge,
        }
    }
}

impl From<ZoneKind> for v2t_model::metrics::ConflictKind {
    fn from(k: ZoneKind) -> Self {
        match k {
            ZoneKind::Crossing => Self::Crossing,
            ZoneKind::Merge => Self::Merge,
        }
    }
}

wire_enum!(
    /// Outcome of one regulator decision.
    PlanStatus, "plan status" {
        /// The plan meets the target.
        Regulating = 1,
        /// The target cannot be met within limits; the plan comes as close as it can.
        Degraded = 2,
        /// The BV gives way to keep the VUT safe.
        SafetyYield = 3,
        /// Yield: the BV waits before the zone.
        Waiting = 4,
        /// The interaction is over; the BV follows its reference.
        Passed = 5,
        /// Inputs are stale: minimal-risk deceleration.
        Stale = 6,
        /// The solver failed; fallback deceleration.
        Fallback = 7,
        /// No prior is active: the BV holds still.
        NoPrior = 8,
    }
);

wire_enum!(
    /// Why the regulator reports τ out of the VUT's reach (`v2t_game::regulator::BelowReachCause`);
    /// code 0 on the wire means "nothing says so".
    BelowReachCode, "below-reach cause" {
        /// Yield, and the VUT stands before the zone while the BV holds back.
        VutWaits = 1,
        /// Earlier runs of this test against this VUT: the PET did not follow the aim.
        Campaign = 2,
        /// Earlier runs: no PET in the asked order twice in a row.
        OrderRefused = 3,
    }
);

wire_enum!(
    /// Drive-by-wire mode reported by the vehicle.
    DbwMode, "drive-by-wire mode" {
        /// The driver drives; commands are ignored.
        Manual = 0,
        /// Commands are executed.
        Auto = 1,
        /// The safety driver overrode the commands.
        Override = 2,
        /// The DBW system has a fault.
        Fault = 3,
    }
);

wire_enum!(
    /// State of the actuation safety gate (`v2t-can`'s gate works in these).
    GateState, "gate state" {
        /// Commands do not reach the actuators (`enable = false`).
        Disengaged = 0,
        /// Commands inside the envelope reach the actuators.
        Engaged = 1,
        /// The gate brakes the vehicle to a standstill on its own profile.
        MinimalRiskStop = 2,
        /// Latched for good: the gate cannot work (invalid configuration, or an internal error).
        Fault = 3,
    }
);

wire_enum!(
    /// Why the gate is where it is: the last transition.
    GateReason, "gate reason" {
        /// Start-up.
        Init = 0,
        /// Engaged on request.
        EngageRequest = 1,
        /// Disengaged on request (`Disengage` or `Reset`).
        DisengageRequest = 2,
        /// The command timed out.
        CommandTimeout = 3,
        /// The vehicle feedback timed out (or its speed was not finite).
        FeedbackTimeout = 4,
        /// A non-finite command arrived.
        NonFiniteCommand = 5,
        /// A minimal-risk stop was requested.
        StopRequest = 6,
        /// Emergency stop.
        EStop = 7,
        /// The DBW reported a fault, an override or an unknown mode.
        DbwFault = 8,
        /// Engage refused: inputs not fresh or not finite, or the DBW not ready.
        EngageRefused = 9,
        /// CAN bus error.
        BusError = 10,
    }
);

wire_enum!(
    /// An onboard node.
    NodeKind, "node" {
        /// Fuses localization and CAN feedback into the BV state.
        State = 1,
        /// Runs the Stackelberg regulator.
        Regulator = 2,
        /// PID + Stanley tracking.
        Tracker = 3,
        /// Safety gate and CAN I/O.
        Gateway = 4,
        /// Watchdog.
        Monitor = 5,
        /// The simulated drive-by-wire ECU.
        SimEcu = 6,
        /// The cloud link (MQTT).
        Uplink = 7,
    }
);

wire_enum!(
    /// What the monitor (or the operator) asks of the gateway.
    SafetyAction, "safety action" {
        /// Everything healthy: engage (or stay engaged).
        Engage = 1,
        /// Stop on the minimal-risk profile.
        MinimalRiskStop = 2,
        /// Disengage (hand back to the safety driver).
        Disengage = 3,
        /// Emergency stop.
        EStop = 4,
        /// Leave a stop (back to disengaged); engaging again is a separate request.
        Reset = 5,
    }
);

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip<T: Code + PartialEq + core::fmt::Debug>() {
        for v in T::ALL {
            assert_eq!(T::from_code(v.code()), Ok(*v));
        }
        let codes: Vec<u8> = T::ALL.iter().map(|v| v.code()).collect();
        for c in 0..=u8::MAX {
            assert_eq!(T::from_code(c).is_ok(), codes.contains(&c), "{} {c}", T::WHAT);
        }
    }

    #[test]
    fn every_code_round_trips_and_unknown_codes_are_errors() {
        round_trip::<StyleCode>();
        round_trip::<ZoneKind>();
        round_trip::<PlanStatus>();
        round_trip::<BelowReachCode>();
        round_trip::<DbwMode>();
        round_trip::<GateState>();
        round_trip::<GateReason>();
        round_trip::<NodeKind>();
        round_trip::<SafetyAction>();
        let e = GateState::from_code(9).unwrap_err();
        assert_eq!(e.to_string(), "unknown gate state code 9");
    }
}
