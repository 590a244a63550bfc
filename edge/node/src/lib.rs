//! The BV's onboard runtime: separate processes (state, regulator, tracker, CAN gateway, monitor,
//! uplink) that talk over iceoryx2 zero-copy shared memory, and a launcher that supervises them.
//! It does not link the simulator: the simulated drive-by-wire ECU that closes the loop without a
//! vehicle, and the benches, are the lab's (`v2t-lab`, binaries `v2t-sim-ecu` and `v2t-bench`).
//!
//! Node code is generic over the iceoryx2 service type: `ipc::Service` between processes,
//! `local::Service` inside one test process. Every node runs the same way: open its ports, then
//! loop until SIGINT/SIGTERM (iceoryx2's signal handling), publishing a heartbeat every
//! `timing.heartbeat_period_s`. The monitor turns a silent node or a stale state into a
//! minimal-risk stop, and the gateway's own command timeout does the same if the monitor is gone.
//!
//! - [`state`]: GNSS/INS fixes and CAN feedback → the BV's state;
//! - [`regulate`]: the Stackelberg regulator of `v2t-game` on the active prior → plans;
//! - [`track`]: PID + Stanley (`v2t-track`) → actuation requests;
//! - [`gateway`]: the safety gate and the DBC codec of `v2t-can` on SocketCAN (or the iceoryx2
//!   virtual bus, [`canbus`], where the kernel has no CAN);
//! - [`monitor`]: heartbeats and freshness → the gate's engage or minimal-risk stop;
//! - [`uplink`]: the cloud link over MQTT: signed priors and commands in (checked by [`prior`]:
//!   signature and time window first, then the BV's speed, acceleration, jerk and lateral limits,
//!   the track's drivable area and a conflict zone with the VUT), telemetry at 10 Hz, heartbeats
//!   at 5 Hz and every verdict out, and the link-loss policy;
//! - [`launch`]: starts every configured node as a process, restarts a failed one, stops all on
//!   SIGINT/SIGTERM; [`realtime`]: opt-in `SCHED_FIFO`, CPU sets and locked memory per process;
//!   [`operator`]: engage, stop, reset, disengage, emergency stop by hand;
//! - [`config`]: `config/edge/<bv>.toml` and the files it names, checked before anything starts;
//!   [`check`]: all of it, and how it fits this machine, one line per check (`v2t-edge check`).

use serde::{Deserialize, Serialize};
use v2t_wire::NodeKind;

pub mod campaign;
pub mod canbus;
pub mod check;
pub mod clock;
pub mod config;
pub mod error;
pub mod gateway;
pub mod heart;
pub mod launch;
pub mod monitor;
pub mod operator;
pub mod ports;
pub mod prior;
pub mod realtime;
pub mod regulate;
pub mod state;
pub mod track;
pub mod uplink;

/// A node of the runtime, as named in the configuration and on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum NodeRole {
    /// Localization + CAN feedback → BV state.
    State,
    /// The Stackelberg regulator.
    Regulator,
    /// PID + Stanley tracking.
    Tracker,
    /// Safety gate and CAN I/O.
    Gateway,
    /// Watchdog.
    Monitor,
    /// The cloud link: priors and commands in, telemetry out (MQTT).
    Uplink,
}

impl NodeRole {
    /// The wire code of this node.
    pub fn kind(self) -> NodeKind {
        match self {
            Self::State => NodeKind::State,
            Self::Regulator => NodeKind::Regulator,
            Self::Tracker => NodeKind::Tracker,
            Self::Gateway => NodeKind::Gateway,
            Self::Monitor => NodeKind::Monitor,
            Self::Uplink => NodeKind::Uplink,
        }
    }

    /// The name used on the command line and for the iceoryx2 node.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::State => "state",
            Self::Regulator => "regulator",
            Self::Tracker => "tracker",
            Self::Gateway => "gateway",
            Self::Monitor => "monitor",
            Self::Uplink => "uplink",
        }
    }
}
