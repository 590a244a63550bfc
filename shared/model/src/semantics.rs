//! What the vision-language model (VLM) must extract from a driving video (paper eq. 2):
//! `s = (Ψ, e, {b_i, φ_i, γ_i}, M)`: the road topology Ψ, the ego vehicle e, each interacting
//! background vehicle (BV) with its behaviour b_i, interaction type φ_i and style γ_i, and the event
//! description M.
//!
//! [`scenario_semantics_schema`] is the JSON Schema the VLM is asked to fill; its descriptions are the
//! doc comments below. [`parse_semantics_json`] turns the model's answer into a checked
//! [`ScenarioSemantics`], or says what is wrong and where.
//!
//! ```
//! use v2t_model::semantics::{parse_semantics_json, InteractionType, SemanticsError};
//! let text = include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/examples/semantics_cut_in.json"));
//! let s = parse_semantics_json(text).unwrap();
//! assert_eq!(s.interacting_bvs[0].interaction_type, InteractionType::CutIn);
//! let bad = text.replace("\"adjacent_right\"", "\"oncoming\"");
//! let Err(SemanticsError::Invalid(e)) = parse_semantics_json(&bad) else { panic!() };
//! assert_eq!(e.field, "interacting_bvs[0].relative_start");
//! ```

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::validate::{Validate, ValidationError, in_range, positive};
use crate::{Style, Target};

/// Highest speed estimate accepted, m/s (252 km/h); anything faster is a misreading.
pub const MAX_SPEED_MPS: f64 = 70.0;
/// Most interacting BVs in one scenario.
pub const MAX_INTERACTING_BVS: usize = 2;
/// Most lanes per direction accepted.
pub const MAX_LANES_PER_DIRECTION: u8 = 8;

/// A unit-only enum with its JSON names (snake_case, as serde writes them), `ALL`, `as_str` and `Display`.
macro_rules! json_enum {
    ($(#[$meta:meta])* pub enum $ty:ident { $($(#[$vmeta:meta])* $variant:ident => $name:literal,)+ }) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
        #[serde(rename_all = "snake_case")]
        pub enum $ty {
            $($(#[$vmeta])* $variant,)+
        }

        impl $ty {
            /// Every variant, in declaration order.
            pub const ALL: &'static [Self] = &[$(Self::$variant),+];

            /// The name used in JSON.
            pub const fn as_str(self) -> &'static str {
                match self {
                    $(Self::$variant => $name),+
                }
            }
        }

        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.as_str())
            }
        }
    };
}

/// Scenario semantics extracted from one driving video (paper eq. 2, `s = (Ψ, e, {b_i, φ_i, γ_i}, M)`).
///
/// Speeds are in m/s, times in s. Left, right, ahead, behind and oncoming are seen from the ego
/// vehicle, the one that carries the camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSemantics {
    /// The road layout where the interaction happens (Ψ).
    pub road_topology: RoadTopology,
    /// The ego vehicle: the one that carries the camera (e).
    pub ego: EgoVehicle,
    /// The one or two background vehicles (BVs) whose interaction with the ego makes the event
    /// safety-critical ({b_i, φ_i, γ_i}). List the most critical one first; leave out traffic that
    /// does not take part.
    #[schemars(length(min = 1, max = 2))]
    pub interacting_bvs: Vec<InteractingBv>,
    /// One to three sentences on the safety-critical event, in the order it happens: who does what,
    /// where, and who passes the conflict point first (M).
    #[schemars(length(min = 1))]
    pub event_description: String,
    /// Post-encroachment time (PET) measured in the source video, s, in [0.1, 30]. An annotation the
    /// operator supplies with the video: copy the value given in the request exactly; never infer,
    /// estimate or round it from the video.
    #[schemars(range(min = 0.1, max = 30.0))]
    pub pet_label_s: f64,
    /// Where this document comes from.
    pub source: SourceMetadata,
}

/// The road layout (Ψ).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RoadTopology {
    /// The kind of road where the interaction happens.
    pub road_type: RoadType,
    /// Lanes in the ego's direction of travel, 1 to 8, at the point where the ego starts.
    #[schemars(range(min = 1, max = 8))]
    pub lanes_per_direction: u8,
    /// Number of roads (arms) that meet at the junction, 3 to 6. Required for `intersection` and
    /// `roundabout`; exactly 3 for `t_junction`; leave it out for other road types.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 3, max = 6))]
    pub junction_arms: Option<u8>,
    /// Whether traffic lights control the junction or road section.
    pub signal_control: SignalControl,
}

json_enum! {
    /// The kind of road.
    pub enum RoadType {
        /// A junction of three to six roads that cross (not a roundabout).
        Intersection => "intersection",
        /// A straight road section without a junction.
        Straight => "straight",
        /// A road section where an on-ramp or an ending lane joins the ego's road.
        Merge => "merge",
        /// A curved road section without a junction.
        Curve => "curve",
        /// A roundabout.
        Roundabout => "roundabout",
        /// A junction where one road ends at another (three arms).
        TJunction => "t_junction",
        /// Anything else (parking lot, gate, unclear).
        Other => "other",
    }
}

json_enum! {
    /// Traffic-light control.
    pub enum SignalControl {
        /// Traffic lights are visible and control the traffic.
        Signalized => "signalized",
        /// No traffic lights (signs or priority rules only).
        Unsignalized => "unsignalized",
        /// Cannot tell from the video.
        Unknown => "unknown",
    }
}

/// The ego vehicle (e).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct EgoVehicle {
    /// Where the ego is when the video starts.
    pub start_lane: StartLane,
    /// What the ego does during the event.
    pub maneuver: Maneuver,
    /// The ego's speed when the event starts, m/s, 0 to 70 (e.g. 13.9 m/s = 50 km/h).
    #[schemars(range(min = 0.0, max = 70.0))]
    pub speed_estimate_mps: f64,
}

/// The ego's starting lane.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StartLane {
    /// Lane the ego starts in, counted from the left among the lanes of its direction of travel:
    /// 1 = leftmost, at most `lanes_per_direction`. Leave it out if unclear.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1, max = 8))]
    pub lane_index_from_left: Option<u8>,
    /// At a junction only: the arm the ego arrives from. Use compass directions when the video shows
    /// them (map overlay, signs); otherwise `from_south`, the convention that puts the ego's arm at
    /// the bottom of the map. Leave it out elsewhere.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub approach: Option<Approach>,
}

json_enum! {
    /// The junction arm a vehicle arrives from.
    pub enum Approach {
        /// Arrives from the south arm, heading north.
        FromSouth => "from_south",
        /// Arrives from the north arm, heading south.
        FromNorth => "from_north",
        /// Arrives from the east arm, heading west.
        FromEast => "from_east",
        /// Arrives from the west arm, heading east.
        FromWest => "from_west",
    }
}

json_enum! {
    /// What a vehicle does during the event.
    pub enum Maneuver {
        /// Keeps its lane and goes straight on (also through a junction).
        Straight => "straight",
        /// Turns left at a junction.
        LeftTurn => "left_turn",
        /// Turns right at a junction.
        RightTurn => "right_turn",
        /// Moves into the lane on its left.
        LaneChangeLeft => "lane_change_left",
        /// Moves into the lane on its right.
        LaneChangeRight => "lane_change_right",
        /// Joins the road from an on-ramp or an ending lane.
        Merge => "merge",
        /// Turns around to go back the way it came.
        UTurn => "u_turn",
    }
}

/// One background vehicle that interacts with the ego (b_i, φ_i, γ_i).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct InteractingBv {
    /// Short unique id: "bv1", "bv2".
    #[schemars(length(min = 1))]
    pub id: String,
    /// Where this BV is, relative to the ego, when the event starts.
    pub relative_start: RelativeStart,
    /// What this BV does (b_i).
    pub behavior: BvBehavior,
    /// The kind of conflict between this BV and the ego (φ_i).
    pub interaction_type: InteractionType,
    /// Who passes the conflict point first (γ_i): `rush` = this BV before the ego, `yield` = the ego
    /// before this BV.
    pub style: Style,
}

json_enum! {
    /// Where a BV starts, seen from the ego.
    pub enum RelativeStart {
        /// In front of the ego, in the ego's lane.
        Ahead => "ahead",
        /// Behind the ego, in the ego's lane.
        Behind => "behind",
        /// In the lane (or on the ramp) to the ego's left, same direction of travel.
        AdjacentLeft => "adjacent_left",
        /// In the lane (or on the ramp) to the ego's right, same direction of travel.
        AdjacentRight => "adjacent_right",
        /// Coming towards the ego from the opposite direction.
        Oncoming => "oncoming",
        /// On a crossing road, arriving from the ego's left.
        CrossingFromLeft => "crossing_from_left",
        /// On a crossing road, arriving from the ego's right.
        CrossingFromRight => "crossing_from_right",
    }
}

/// What a BV does (b_i).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BvBehavior {
    /// This BV's maneuver during the event.
    pub maneuver: Maneuver,
    /// This BV's speed when the event starts, m/s, 0 to 70.
    #[schemars(range(min = 0.0, max = 70.0))]
    pub speed_estimate_mps: f64,
    /// One sentence on this BV: what it is, where it goes, how it drives (speeding up, braking,
    /// gap it leaves).
    #[schemars(length(min = 1))]
    pub description: String,
}

json_enum! {
    /// The kind of conflict between a BV and the ego (φ_i).
    pub enum InteractionType {
        /// The BV changes into the ego's lane close in front of it (BV: lane_change_left from
        /// adjacent_right, lane_change_right from adjacent_left, or merge).
        CutIn => "cut_in",
        /// At an intersection or T-junction, the ego or the BV turns left across the other's path
        /// without a protected signal phase (BV oncoming or crossing).
        UnprotectedLeftTurn => "unprotected_left_turn",
        /// The ego or the BV joins the other's lane where lanes merge.
        Merge => "merge",
        /// The ego or the BV changes lanes next to the other (not close in front: see `cut_in`).
        LaneChange => "lane_change",
        /// The BV crosses the ego's path on a crossing road.
        Crossing => "crossing",
        /// The ego or the BV turns right across or into the other's path.
        RightTurn => "right_turn",
        /// Ego and BV in the same lane, one closing in on the other from behind.
        RearEnd => "rear_end",
        /// Any other conflict.
        Other => "other",
    }
}

/// Where a semantics document comes from. Filled by the pipeline, not by the model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SourceMetadata {
    /// The source video: file name or URI.
    #[schemars(length(min = 1))]
    pub video: String,
    /// The data set the video comes from, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dataset: Option<String>,
    /// Length of the video, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub duration_s: Option<f64>,
    /// Number of video frames shown to the model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1))]
    pub frames_used: Option<u32>,
    /// Id of the vision-language model that produced the document.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<String>,
    /// Version of the prompt used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prompt_version: Option<String>,
}

/// Why a semantics document was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SemanticsError {
    /// Not JSON, or not of the schema's shape (unknown or missing field, wrong type, number out of range).
    #[error("semantics JSON, line {line} column {column}: {message}")]
    Json {
        /// 1-based line of the problem.
        line: usize,
        /// 1-based column of the problem.
        column: usize,
        /// What serde_json found wrong.
        message: String,
    },
    /// Well-formed, but a value is out of range or inconsistent with another.
    #[error("invalid semantics: {0}")]
    Invalid(#[from] ValidationError),
}

impl From<serde_json::Error> for SemanticsError {
    fn from(e: serde_json::Error) -> Self {
        let text = e.to_string();
        let suffix = format!(" at line {} column {}", e.line(), e.column());
        let message = text.strip_suffix(&suffix).unwrap_or(&text).to_owned();
        Self::Json { line: e.line(), column: e.column(), message }
    }
}

/// The JSON Schema of [`ScenarioSemantics`], as given to the VLM and committed in
/// `config/schema/scenario_semantics.schema.json`.
pub fn scenario_semantics_schema() -> serde_json::Value {
    schemars::schema_for!(ScenarioSemantics).to_value()
}

/// Parses and validates a semantics document.
pub fn parse_semantics_json(text: &str) -> Result<ScenarioSemantics, SemanticsError> {
    let semantics: ScenarioSemantics = serde_json::from_str(text)?;
    semantics.validate()?;
    Ok(semantics)
}

impl Validate for ScenarioSemantics {
    fn validate(&self) -> Result<(), ValidationError> {
        self.road_topology.validate().map_err(|e| e.within("road_topology"))?;
        self.ego.validate_on(&self.road_topology).map_err(|e| e.within("ego"))?;
        self.validate_bvs()?;
        non_blank("event_description", &self.event_description)?;
        Target::check_tau("pet_label_s", self.pet_label_s)?;
        self.source.validate().map_err(|e| e.within("source"))
    }
}

impl ScenarioSemantics {
    fn validate_bvs(&self) -> Result<(), ValidationError> {
        let count = self.interacting_bvs.len();
        if !(1..=MAX_INTERACTING_BVS).contains(&count) {
            return Err(ValidationError::new(
                "interacting_bvs",
                format!("must list 1 or {MAX_INTERACTING_BVS} interacting BVs, got {count}"),
            ));
        }
        for (i, bv) in self.interacting_bvs.iter().enumerate() {
            let at = |e: ValidationError| e.within(&format!("[{i}]")).within("interacting_bvs");
            bv.validate().map_err(at)?;
            if let Some(j) = self.interacting_bvs.iter().take(i).position(|other| other.id == bv.id) {
                let problem = format!("`{}` is already the id of interacting_bvs[{j}]; ids must be unique", bv.id);
                return Err(at(ValidationError::new("id", problem)));
            }
            check_interaction(bv, &self.ego, self.road_topology.road_type).map_err(at)?;
        }
        Ok(())
    }
}

impl Validate for RoadTopology {
    fn validate(&self) -> Result<(), ValidationError> {
        let lanes = self.lanes_per_direction;
        if !(1..=MAX_LANES_PER_DIRECTION).contains(&lanes) {
            return Err(ValidationError::new(
                "lanes_per_direction",
                format!("must lie in 1..={MAX_LANES_PER_DIRECTION}, got {lanes}"),
            ));
        }
        let road = self.road_type;
        let problem = match (road, self.junction_arms) {
            (RoadType::TJunction, Some(3)) => None,
            (RoadType::TJunction, arms) => {
                Some(format!("a t_junction has exactly 3 arms, got {}", arms.map_or("none".into(), |n| n.to_string())))
            }
            (RoadType::Intersection | RoadType::Roundabout, None) => {
                Some(format!("is required for road_type `{road}`: the number of roads that meet there, 3 to 6"))
            }
            (_, Some(arms)) if !(3..=6).contains(&arms) => Some(format!("must lie in 3..=6, got {arms}")),
            _ => None,
        };
        problem.map_or(Ok(()), |p| Err(ValidationError::new("junction_arms", p)))
    }
}

impl EgoVehicle {
    /// Checks the ego's own values and its lane against the road.
    fn validate_on(&self, road: &RoadTopology) -> Result<(), ValidationError> {
        if let Some(lane) = self.start_lane.lane_index_from_left
            && !(1..=road.lanes_per_direction).contains(&lane)
        {
            return Err(ValidationError::new(
                "start_lane.lane_index_from_left",
                format!("must lie in 1..={} (road_topology.lanes_per_direction), got {lane}", road.lanes_per_direction),
            ));
        }
        speed("speed_estimate_mps", self.speed_estimate_mps)
    }
}

impl Validate for InteractingBv {
    fn validate(&self) -> Result<(), ValidationError> {
        non_blank("id", &self.id)?;
        self.behavior.validate().map_err(|e| e.within("behavior"))
    }
}

impl Validate for BvBehavior {
    fn validate(&self) -> Result<(), ValidationError> {
        speed("speed_estimate_mps", self.speed_estimate_mps)?;
        non_blank("description", &self.description)
    }
}

impl Validate for SourceMetadata {
    fn validate(&self) -> Result<(), ValidationError> {
        non_blank("video", &self.video)?;
        if let Some(duration) = self.duration_s {
            positive("duration_s", duration)?;
        }
        if self.frames_used == Some(0) {
            return Err(ValidationError::new("frames_used", "must be at least 1, got 0"));
        }
        Ok(())
    }
}

/// Whether a BV's start, its maneuver, the ego's maneuver and the road fit its interaction type.
/// Field paths are relative to the BV.
fn check_interaction(bv: &InteractingBv, ego: &EgoVehicle, road: RoadType) -> Result<(), ValidationError> {
    use InteractionType as I;
    use Maneuver as M;
    use RelativeStart as R;

    let kind = bv.interaction_type;
    let start = bv.relative_start;
    let bv_maneuver = bv.behavior.maneuver;
    let ego_maneuver = ego.maneuver;
    let either_does = |ms: &[Maneuver]| ms.contains(&ego_maneuver) || ms.contains(&bv_maneuver);
    let start_must_be = |allowed: &[RelativeStart], why: &str| {
        if allowed.contains(&start) {
            Ok(())
        } else {
            Err(ValidationError::new(
                "relative_start",
                format!("`{start}` does not fit interaction_type `{kind}`: {why} {}", one_of(allowed)),
            ))
        }
    };
    let lane_changes = [M::LaneChangeLeft, M::LaneChangeRight, M::Merge];
    let needs_maneuver = |wanted: &[Maneuver]| {
        Err(ValidationError::new(
            "interaction_type",
            format!(
                "`{kind}` needs the ego or this BV to make {}, but the ego makes `{ego_maneuver}` and the BV \
                 `{bv_maneuver}`",
                one_of(wanted)
            ),
        ))
    };

    match kind {
        I::CutIn => {
            start_must_be(&[R::AdjacentLeft, R::AdjacentRight, R::Ahead, R::Behind], "a cut-in BV starts")?;
            let fitting: &[Maneuver] = match start {
                R::AdjacentRight => &[M::LaneChangeLeft, M::Merge],
                R::AdjacentLeft => &[M::LaneChangeRight, M::Merge],
                _ => &lane_changes,
            };
            if !fitting.contains(&bv_maneuver) {
                return Err(ValidationError::new(
                    "behavior.maneuver",
                    format!(
                        "`{bv_maneuver}` does not fit a `cut_in` from `{start}`: the BV must make {}",
                        one_of(fitting)
                    ),
                ));
            }
        }
        I::UnprotectedLeftTurn => {
            if !matches!(road, RoadType::Intersection | RoadType::TJunction) {
                return Err(ValidationError::new(
                    "interaction_type",
                    format!("`{kind}` needs road_topology.road_type `intersection` or `t_junction`, got `{road}`"),
                ));
            }
            if !either_does(&[M::LeftTurn]) {
                return needs_maneuver(&[M::LeftTurn]);
            }
            start_must_be(
                &[R::Oncoming, R::CrossingFromLeft, R::CrossingFromRight],
                "the BV of a left-turn conflict starts",
            )?;
        }
        I::Merge | I::LaneChange => {
            if !either_does(&lane_changes) {
                return needs_maneuver(&lane_changes);
            }
        }
        I::Crossing => start_must_be(&[R::CrossingFromLeft, R::CrossingFromRight], "a crossing BV starts")?,
        I::RightTurn => {
            if !either_does(&[M::RightTurn]) {
                return needs_maneuver(&[M::RightTurn]);
            }
        }
        I::RearEnd => start_must_be(&[R::Ahead, R::Behind], "a rear-end BV starts")?,
        I::Other => {}
    }
    Ok(())
}

/// "`a`", "`a` or `b`", "`a`, `b` or `c`".
fn one_of<T: std::fmt::Display>(items: &[T]) -> String {
    let names: Vec<String> = items.iter().map(|item| format!("`{item}`")).collect();
    match names.split_last() {
        None => String::new(),
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
    }
}

fn non_blank(field: &str, text: &str) -> Result<(), ValidationError> {
    if text.trim().is_empty() { Err(ValidationError::new(field, "must not be empty")) } else { Ok(()) }
}

fn speed(field: &str, speed_mps: f64) -> Result<(), ValidationError> {
    in_range(field, speed_mps, 0.0, MAX_SPEED_MPS)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use proptest::sample::select;

    const SCHEMA_PATH: &str =
        concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/schema/scenario_semantics.schema.json");
    const CUT_IN: &str =
        include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/examples/semantics_cut_in.json"));
    const LEFT_TURN: &str =
        include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/examples/semantics_left_turn.json"));

    fn cut_in() -> ScenarioSemantics {
        parse_semantics_json(CUT_IN).unwrap()
    }

    fn left_turn() -> ScenarioSemantics {
        parse_semantics_json(LEFT_TURN).unwrap()
    }

    /// The field the first problem names.
    fn rejected_field(s: &ScenarioSemantics) -> String {
        s.validate().expect_err("should be rejected").field
    }

    fn json_error(text: &str) -> (usize, String) {
        match parse_semantics_json(text) {
            Err(SemanticsError::Json { line, message, .. }) => (line, message),
            other => panic!("expected a JSON error, got {other:?}"),
        }
    }

    #[test]
    fn committed_schema_matches_the_types() {
        let generated = serde_json::to_string_pretty(&scenario_semantics_schema()).unwrap() + "\n";
        if std::env::var("V2T_BLESS_SCHEMA").as_deref() == Ok("1") {
            std::fs::write(SCHEMA_PATH, &generated).unwrap();
            return;
        }
        let committed = std::fs::read_to_string(SCHEMA_PATH).unwrap_or_default();
        let first_difference = committed.lines().zip(generated.lines()).position(|(a, b)| a != b).map_or(0, |i| i + 1);
        assert!(
            committed == generated,
            "{SCHEMA_PATH} is out of date with the types in semantics.rs (first difference near line \
             {first_difference}); regenerate it with \
             `V2T_BLESS_SCHEMA=1 cargo test -p v2t-model semantics::tests::committed_schema_matches_the_types` \
             and commit it"
        );
    }

    #[test]
    fn schema_carries_ranges_and_descriptions() {
        let schema = scenario_semantics_schema().to_string();
        for needle in ["\"additionalProperties\":false", "\"exclusiveMinimum\":0.0", "never infer", "m/s", "\"u_turn\""]
        {
            assert!(schema.contains(needle), "schema lacks {needle}");
        }
    }

    #[test]
    fn examples_parse_validate_and_round_trip() {
        for s in [cut_in(), left_turn()] {
            let text = serde_json::to_string_pretty(&s).unwrap();
            assert_eq!(parse_semantics_json(&text).unwrap(), s);
        }
        assert!((cut_in().pet_label_s - 4.70).abs() < 1e-12);
        assert_eq!(left_turn().interacting_bvs[0].interaction_type, InteractionType::UnprotectedLeftTurn);
    }

    #[test]
    fn json_names_match_serde() {
        fn check<T: Serialize + std::fmt::Display>(all: &[T]) {
            for v in all {
                assert_eq!(serde_json::to_value(v).unwrap(), serde_json::Value::String(v.to_string()));
            }
        }
        check(RoadType::ALL);
        check(SignalControl::ALL);
        check(Approach::ALL);
        check(Maneuver::ALL);
        check(RelativeStart::ALL);
        check(InteractionType::ALL);
    }

    #[test]
    fn unknown_fields_are_rejected() {
        let mut doc: serde_json::Value = serde_json::from_str(CUT_IN).unwrap();
        doc["ego"]["confidence"] = serde_json::json!(0.9);
        let (_, message) = json_error(&doc.to_string());
        assert!(message.contains("unknown field `confidence`"), "{message}");
        let mut doc: serde_json::Value = serde_json::from_str(CUT_IN).unwrap();
        doc["interacting_bvs"][0]["behavior"]["speed_mps"] = serde_json::json!(3.0);
        let (_, message) = json_error(&doc.to_string());
        assert!(message.contains("unknown field `speed_mps`"), "{message}");
    }

    #[test]
    fn out_of_range_numbers_are_rejected_where_they_are() {
        let text = CUT_IN.replace("\"pet_label_s\": 4.70", "\"pet_label_s\": 1e999");
        assert_ne!(text, CUT_IN);
        let line = 1 + CUT_IN.lines().position(|l| l.contains("\"pet_label_s\"")).unwrap();
        let (at, message) = json_error(&text);
        assert_eq!(at, line, "{message}");

        let mut s = cut_in();
        s.interacting_bvs[0].behavior.speed_estimate_mps = -1.0;
        assert_eq!(rejected_field(&s), "interacting_bvs[0].behavior.speed_estimate_mps");
        s.interacting_bvs[0].behavior.speed_estimate_mps = f64::NAN;
        assert_eq!(rejected_field(&s), "interacting_bvs[0].behavior.speed_estimate_mps");
        let mut s = cut_in();
        s.ego.speed_estimate_mps = 70.5;
        assert_eq!(rejected_field(&s), "ego.speed_estimate_mps");
    }

    #[test]
    fn bv_count_must_be_one_or_two() {
        let mut s = cut_in();
        s.interacting_bvs.clear();
        assert_eq!(rejected_field(&s), "interacting_bvs");
        let bv = cut_in().interacting_bvs[0].clone();
        for id in ["bv2", "bv3"] {
            s.interacting_bvs.push(InteractingBv { id: id.into(), ..bv.clone() });
        }
        s.interacting_bvs.push(bv);
        assert_eq!(rejected_field(&s), "interacting_bvs");
        s.interacting_bvs.pop();
        assert_eq!(s.validate(), Ok(()));
    }

    #[test]
    fn bv_ids_must_be_unique_and_non_empty() {
        let mut s = cut_in();
        s.interacting_bvs.push(s.interacting_bvs[0].clone());
        let e = s.validate().unwrap_err();
        assert_eq!(e.field, "interacting_bvs[1].id");
        assert!(e.problem.contains("unique"), "{e}");
        s.interacting_bvs[1].id = " ".into();
        assert_eq!(rejected_field(&s), "interacting_bvs[1].id");
    }

    #[test]
    fn pet_label_must_lie_in_range() {
        let text = CUT_IN.replace("\"pet_label_s\": 4.70", "\"pet_label_s\": 0");
        let Err(SemanticsError::Invalid(e)) = parse_semantics_json(&text) else { panic!("accepted a zero PET") };
        assert_eq!(e.field, "pet_label_s");
        let mut s = cut_in();
        for pet in [-1.0, 0.05, 30.01, f64::NAN, f64::INFINITY] {
            s.pet_label_s = pet;
            assert_eq!(rejected_field(&s), "pet_label_s");
        }
        s.pet_label_s = 30.0;
        assert_eq!(s.validate(), Ok(()));
    }

    #[test]
    fn inconsistent_interactions_name_the_field_and_the_fix() {
        let e = {
            let mut s = cut_in();
            s.interacting_bvs[0].relative_start = RelativeStart::Oncoming;
            s.validate().unwrap_err()
        };
        assert_eq!(e.field, "interacting_bvs[0].relative_start");
        assert!(e.problem.contains("`adjacent_left`, `adjacent_right`, `ahead` or `behind`"), "{e}");

        use {InteractionType as I, Maneuver as M, RelativeStart as R};
        fn bv0(s: &mut ScenarioSemantics) -> &mut InteractingBv {
            &mut s.interacting_bvs[0]
        }
        type Example = fn() -> ScenarioSemantics;
        type Edit = fn(&mut ScenarioSemantics);
        let cases: [(Example, Edit, &str); 11] = [
            (cut_in, |s| bv0(s).behavior.maneuver = M::LaneChangeRight, "interacting_bvs[0].behavior.maneuver"),
            (cut_in, |s| bv0(s).interaction_type = I::Crossing, "interacting_bvs[0].relative_start"),
            (cut_in, |s| s.road_topology.lanes_per_direction = 0, "road_topology.lanes_per_direction"),
            (cut_in, |s| s.road_topology.junction_arms = Some(9), "road_topology.junction_arms"),
            (cut_in, |s| s.ego.start_lane.lane_index_from_left = Some(4), "ego.start_lane.lane_index_from_left"),
            (cut_in, |s| s.event_description = " ".into(), "event_description"),
            (cut_in, |s| s.source.duration_s = Some(0.0), "source.duration_s"),
            (left_turn, |s| s.road_topology.junction_arms = None, "road_topology.junction_arms"),
            (left_turn, |s| s.road_topology.road_type = RoadType::Straight, "interacting_bvs[0].interaction_type"),
            (left_turn, |s| bv0(s).behavior.maneuver = M::Straight, "interacting_bvs[0].interaction_type"),
            (left_turn, |s| bv0(s).relative_start = R::Ahead, "interacting_bvs[0].relative_start"),
        ];
        for (example, edit, field) in cases {
            let mut s = example();
            edit(&mut s);
            assert_eq!(rejected_field(&s), field, "{:?}", s.validate());
        }
        // The consistent variants are accepted.
        let mut s = left_turn();
        s.ego.maneuver = Maneuver::LeftTurn;
        s.interacting_bvs[0].behavior.maneuver = Maneuver::Straight;
        assert_eq!(s.validate(), Ok(()));
        s.road_topology.road_type = RoadType::TJunction;
        s.road_topology.junction_arms = Some(3);
        assert_eq!(s.validate(), Ok(()));
    }

    /// Hundredths: the precision a VLM writes, and exact through JSON without serde_json's `float_roundtrip`.
    fn decimal(lo_hundredths: u32, hi_hundredths: u32) -> impl Strategy<Value = f64> {
        (lo_hundredths..=hi_hundredths).prop_map(|c| f64::from(c) / 100.0)
    }

    fn text() -> impl Strategy<Value = String> {
        "[A-Za-z0-9é][ -~é→]{0,40}"
    }

    /// A BV start and maneuver that fit `kind` whatever the ego does.
    fn start_and_maneuver(kind: InteractionType) -> BoxedStrategy<(RelativeStart, Maneuver)> {
        use {InteractionType as I, Maneuver as M, RelativeStart as R};
        let lane_change = || select(&[M::LaneChangeLeft, M::LaneChangeRight, M::Merge][..]);
        match kind {
            I::CutIn => prop_oneof![
                (Just(R::AdjacentRight), select(&[M::LaneChangeLeft, M::Merge][..])),
                (Just(R::AdjacentLeft), select(&[M::LaneChangeRight, M::Merge][..])),
                (select(&[R::Ahead, R::Behind][..]), lane_change()),
            ]
            .boxed(),
            I::UnprotectedLeftTurn => {
                (select(&[R::Oncoming, R::CrossingFromLeft, R::CrossingFromRight][..]), Just(M::LeftTurn)).boxed()
            }
            I::Merge | I::LaneChange => (select(R::ALL), lane_change()).boxed(),
            I::Crossing => (select(&[R::CrossingFromLeft, R::CrossingFromRight][..]), select(M::ALL)).boxed(),
            I::RightTurn => (select(R::ALL), Just(M::RightTurn)).boxed(),
            I::RearEnd => (select(&[R::Ahead, R::Behind][..]), select(M::ALL)).boxed(),
            I::Other => (select(R::ALL), select(M::ALL)).boxed(),
        }
    }

    fn bv(id: &'static str) -> impl Strategy<Value = InteractingBv> {
        let style = prop_oneof![Just(Style::Rush), Just(Style::Yield)];
        (
            select(InteractionType::ALL).prop_flat_map(|kind| (Just(kind), start_and_maneuver(kind))),
            style,
            decimal(0, 7000),
            text(),
        )
            .prop_map(
                move |((interaction_type, (relative_start, maneuver)), style, speed_estimate_mps, description)| {
                    let behavior = BvBehavior { maneuver, speed_estimate_mps, description };
                    InteractingBv { id: id.into(), relative_start, behavior, interaction_type, style }
                },
            )
    }

    /// Consistent semantics: every generated document is valid.
    fn semantics() -> impl Strategy<Value = ScenarioSemantics> {
        use proptest::option::of;
        let bvs = prop_oneof![bv("bv1").prop_map(|a| vec![a]), (bv("bv1"), bv("bv2")).prop_map(|(a, b)| vec![a, b])];
        let road =
            (select(RoadType::ALL), 1..=MAX_LANES_PER_DIRECTION, 3u8..=6, any::<bool>(), select(SignalControl::ALL));
        let ego = (1..=MAX_LANES_PER_DIRECTION, of(select(Approach::ALL)), select(Maneuver::ALL), decimal(0, 7000));
        let source = (text(), of(text()), of(decimal(1, 60_000)), of(1u32..=10_000), of(text()), of(text()));
        (bvs, road, ego, text(), decimal(10, 3000), source).prop_map(|(bvs, road, ego, event, pet, source)| {
            let (mut road_type, lanes_per_direction, arms, with_arms, signal_control) = road;
            // What depends on other parts: a left-turn conflict needs a junction, the lane index the lane count.
            if bvs.iter().any(|bv| bv.interaction_type == InteractionType::UnprotectedLeftTurn)
                && !matches!(road_type, RoadType::Intersection | RoadType::TJunction)
            {
                road_type = RoadType::Intersection;
            }
            let junction_arms = match road_type {
                RoadType::TJunction => Some(3),
                RoadType::Intersection | RoadType::Roundabout => Some(arms),
                _ => with_arms.then_some(arms),
            };
            let (lane, approach, maneuver, speed_estimate_mps) = ego;
            let lane_index_from_left = (lane % 3 != 0).then_some(lane.min(lanes_per_direction));
            let (video, dataset, duration_s, frames_used, model, prompt_version) = source;
            ScenarioSemantics {
                road_topology: RoadTopology { road_type, lanes_per_direction, junction_arms, signal_control },
                ego: EgoVehicle {
                    start_lane: StartLane { lane_index_from_left, approach },
                    maneuver,
                    speed_estimate_mps,
                },
                interacting_bvs: bvs,
                event_description: event,
                pet_label_s: pet,
                source: SourceMetadata { video, dataset, duration_s, frames_used, model, prompt_version },
            }
        })
    }

    proptest! {
        #[test]
        fn valid_semantics_round_trip_through_json(s in semantics()) {
            prop_assert_eq!(s.validate(), Ok(()));
            let text = serde_json::to_string(&s).unwrap();
            prop_assert_eq!(parse_semantics_json(&text), Ok(s.clone()));
            let pretty = serde_json::to_string_pretty(&s).unwrap();
            prop_assert_eq!(parse_semantics_json(&pretty), Ok(s));
        }
    }
}
