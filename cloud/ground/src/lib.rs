//! # v2t-ground
//!
//! Grounding (paper Sec. 3.2.2, Appendix B): a video's [`ScenarioSemantics`] says *what* happens —
//! a four-arm junction, the ego going straight from the south, an oncoming SUV turning left across
//! it and clearing the conflict point 2.9 s before the ego — but not *where on the proving ground*.
//! This crate answers where: it retrieves the map fragment of the [`TopologyLibrary`] that fits, and
//! places the vehicle under test (VUT, the video's ego), each background vehicle (BV) and their
//! conflict on it, as a [`GroundedScenario`] that the trajectory generator and the regulator take.
//!
//! 1. **Retrieval** ([`rank`]): every fragment is scored by structured compatibility — road type
//!    and arm count, lanes per direction, whether the needed maneuvers and conflict anchor exist,
//!    whether the anchor's kind is the one the interaction type names, room before the conflict —
//!    and by BM25 between its description and the video's event and behaviour descriptions. A
//!    fragment without the needed maneuvers is infeasible, with the reason. Every candidate carries
//!    its per-criterion scores and reasons ([`Candidate::explain`]).
//! 2. **Grounding** ([`ground`]), step by step on the best feasible fragment: the VUT's start region
//!    (approach arm, lane from the left) → its entry anchor; its maneuver → the maneuver path and
//!    the exit anchor; each BV from its relative start (the oncoming arm, the arm on the ego's left
//!    or right, the adjacent lane, the ending lane of a merge) and maneuver → its route, a lane
//!    change being a quintic lateral blend that completes at the cut-in or merge anchor; the
//!    conflict anchor both routes share, and the occupancy intervals along both routes from the
//!    vehicles' footprints ([`v2t_model::metrics::conflict_zones`]); speeds from the semantics, and
//!    start times so that each BV and the VUT pass the conflict in the BV's style's order with the
//!    video's PET between them. A fragment that fails hands over to the next; when none fits,
//!    [`GroundError::NoFit`] gives the reason for each.
//!
//! Pure: no IO, no clock. The caller loads the map ([`v2t_map::Map::load`]).
//!
//! ```
//! use v2t_ground::{ground, rank};
//! use v2t_map::{Map, library::TopologyLibrary};
//! use v2t_model::{Style, grounded::AgentRole, semantics::parse_semantics_json};
//!
//! let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
//! let xodr = std::fs::read_to_string(format!("{root}/tests/data/maps/4way_intersection.xodr"))?;
//! let map = Map::parse(&xodr, "4way_intersection")?;
//! let library = TopologyLibrary::build(&map);
//! let json = std::fs::read_to_string(format!("{root}/config/examples/semantics_left_turn.json"))?;
//! let semantics = parse_semantics_json(&json)?;
//!
//! // Retrieval alone: the one junction of the map, with the reasons.
//! let ranking = rank(&library, &semantics);
//! assert!(ranking[0].feasible);
//! println!("{}", ranking[0].explain());
//!
//! // Grounding: the ego from the south arm straight on, the SUV from the north turning left across it.
//! let grounding = ground(&map, &library, &semantics)?;
//! let scenario = &grounding.scenario;
//! assert_eq!(scenario.fragment_id, "J4");
//! assert_eq!((scenario.target.style(), scenario.target.tau_s()), (Style::Rush, 2.9));
//! let vut = scenario.vut().unwrap();
//! assert!(vut.start.anchor_id.starts_with("J4/entry/"));
//! assert_eq!(scenario.bvs().count(), 1);
//! // The planned passage: the SUV leaves the zone 2.9 s before the VUT enters it.
//! let t = &grounding.timing[0];
//! assert!((t.vut_enter_s - t.bv_exit_s - 2.9).abs() < 1e-9);
//! assert_eq!(scenario.agents[0].role, AgentRole::Vut);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! [`ScenarioSemantics`]: v2t_model::semantics::ScenarioSemantics
//! [`TopologyLibrary`]: v2t_map::library::TopologyLibrary
//! [`GroundedScenario`]: v2t_model::grounded::GroundedScenario

mod error;
mod ground;
mod plan;
mod retrieve;
mod route;
pub mod text;
pub mod timing;

pub use error::{GroundError, Rejection};
pub use ground::{AgentRoute, GroundOptions, Grounding, MIN_LEAD_M, MIN_TAIL_M, TAIL_TIME_S, ground, ground_with};
pub use retrieve::{
    Candidate, Criterion, ROOM_MIN_M, ROOM_TIME_S, W_INTERACTION, W_LANES, W_LEXICAL, W_MANEUVERS, W_ROAD, W_ROOM, rank,
};
pub use timing::ConflictTiming;
