//! # v2t-sumo — Eclipse SUMO as the driver of the vehicle under test
//!
//! The simulated proving ground lets SUMO drive the vehicle under test (VUT) while it imposes its
//! own background vehicle (BV) every step. This crate is the bridge, with nothing but `std`:
//!
//! - [`SumoBinaries`] finds SUMO's programs (`$V2T_SUMO_BIN`, the workspace's
//!   `target/sumo-venv` made by `scripts/install-sumo`, or `PATH`); [`convert_map`] turns the
//!   OpenDRIVE map into a SUMO network with `netconvert`;
//! - [`Network`] reads that network (`.net.xml`): lanes, junction lanes, connections; it finds the
//!   lane under a point ([`Network::nearest_lane`]) and the SUMO route that drives a sampled path
//!   ([`Network::match_route`]);
//! - [`Sumo`] is a running `sumo` with a TraCI connection (SUMO's TCP control protocol, API
//!   version ≥ 21; SUMO 1.28 speaks 22): step, add routes and vehicles, teleport a vehicle
//!   ([`MoveToXy`]), read vehicle states, several commands per round trip ([`Sumo::batch`]),
//!   reload a new run in the same process ([`Sumo::load`]);
//! - [`write_additional`] writes the vehicle types of a run.
//!
//! **Positions are front bumpers.** SUMO's vehicle position, lane position, `departPos` and
//! `moveToXY` point are all the centre of the vehicle's *front bumper*; its angles are degrees
//! from north, clockwise ([`traci_angle_deg`], [`heading_rad`]).
//!
//! ```
//! use v2t_sumo::{Network, traci_angle_deg};
//! let net = Network::parse(
//!     r#"<net><edge id="a" from="J0" to="J1"><lane id="a_0" index="0" speed="13.89"
//!          length="100" shape="0,0 100,0"/></edge></net>"#,
//!     std::path::Path::new("inline.net.xml"),
//! )?;
//! let on = net.nearest_lane(40.0, 1.0, 0.0, 2.0).expect("on lane a_0");
//! assert_eq!((on.lane_id.as_str(), on.s_m, on.lateral_m), ("a_0", 40.0, 1.0));
//! assert_eq!(traci_angle_deg(std::f64::consts::FRAC_PI_2), 0.0); // north
//! # Ok::<(), v2t_sumo::SumoError>(())
//! ```

mod additional;
mod binaries;
mod client;
mod error;
mod geometry;
mod net;
mod route;
mod traci;
mod wire;

pub use additional::{VType, additional_xml, vtype_xml, write_additional};
pub use binaries::{SUMO_BIN_VAR, SumoBinaries, convert_map};
pub use client::{StartOptions, Sumo};
pub use error::{INSTALL_HINT, SumoError};
pub use net::{
    Bounds, Connection, DEFAULT_LANE_WIDTH_M, Edge, EdgeFunction, Junction, Lane, LanePos, MAX_HEADING_ERROR_RAD,
    Network,
};
pub use route::MatchedRoute;
pub use traci::{MoveToXy, NewVehicle, Reply, Request, VehicleVar, heading_rad, traci_angle_deg};
