//! The TraCI commands this client sends and the replies they get, as plain data.
//!
//! Ids are those of SUMO 1.28's `traci/constants.py` (TraCI API version 22), checked against the
//! real binary by `tests/sumo.rs`.

/// A vehicle variable read with TraCI's *get vehicle variable* command (0xa4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VehicleVar {
    /// Front bumper centre, x and y in metres (0x42, a `POSITION_2D`).
    Position,
    /// Heading in degrees, navigational: 0 = north (+y), clockwise (0x43).
    Angle,
    /// Speed in m/s (0x40).
    Speed,
    /// Acceleration in m/s² of the last step (0x72).
    Acceleration,
    /// Id of the lane the front bumper is on (0x51).
    LaneId,
    /// Id of the edge the front bumper is on; internal edges start with `:` (0x50).
    RoadId,
    /// Distance in metres of the front bumper from the start of its lane (0x56).
    LanePosition,
}

impl VehicleVar {
    /// TraCI's variable id.
    pub const fn id(self) -> u8 {
        match self {
            Self::Position => 0x42,
            Self::Angle => 0x43,
            Self::Speed => 0x40,
            Self::Acceleration => 0x72,
            Self::LaneId => 0x51,
            Self::RoadId => 0x50,
            Self::LanePosition => 0x56,
        }
    }

    /// The TraCI type of its value.
    pub(crate) const fn value_type(self) -> u8 {
        match self {
            Self::Position => crate::wire::POSITION_2D,
            Self::LaneId | Self::RoadId => crate::wire::TYPE_STRING,
            Self::Angle | Self::Speed | Self::Acceleration | Self::LanePosition => crate::wire::TYPE_DOUBLE,
        }
    }

    /// Its name in SUMO's Python client, for messages.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Position => "getPosition",
            Self::Angle => "getAngle",
            Self::Speed => "getSpeed",
            Self::Acceleration => "getAcceleration",
            Self::LaneId => "getLaneID",
            Self::RoadId => "getRoadID",
            Self::LanePosition => "getLanePosition",
        }
    }
}

/// TraCI `moveToXY` (0xc4, variable 0xb4): teleports a vehicle so that its **front bumper
/// centre** is at `(x, y)` at the end of the next simulation step.
///
/// `keep_route` is SUMO's bit set: `1` maps the point onto the vehicle's current route only; `0`
/// maps it onto any lane of the network (the route becomes that edge); `2` also allows positions
/// off every lane (the vehicle keeps the exact point). `edge` and `lane` are hints that resolve
/// ambiguities; `""` and `-1` leave them open. A point farther than 100 m from any allowed lane is
/// refused (SUMO's default match threshold).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveToXy<'a> {
    /// The vehicle.
    pub vehicle: &'a str,
    /// Edge hint (`""`: none).
    pub edge: &'a str,
    /// Lane index hint (`-1`: none).
    pub lane: i32,
    /// Front bumper x in metres.
    pub x: f64,
    /// Front bumper y in metres.
    pub y: f64,
    /// Heading in TraCI degrees (0 = north, clockwise); see [`traci_angle_deg`].
    pub angle_deg: f64,
    /// SUMO's `keepRoute` bit set (see above).
    pub keep_route: u8,
}

/// TraCI `add` of a vehicle with all its parameters (0xc4, variable 0x85 `ADD_FULL`): a compound
/// of 12 strings and 2 integers; the fields this type does not carry are sent as SUMO's defaults
/// (arrival lane and speed `current`, no TAZ, no line, no persons).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NewVehicle<'a> {
    /// The new vehicle's id.
    pub id: &'a str,
    /// An existing route (see [`Request::AddRoute`]).
    pub route: &'a str,
    /// An existing vehicle type (`DEFAULT_VEHTYPE` always exists).
    pub vehicle_type: &'a str,
    /// Departure time: `now` or seconds.
    pub depart: &'a str,
    /// Departure lane: an index, `first`, `best`, `free`, …
    pub depart_lane: &'a str,
    /// Departure position of the front bumper: metres along the lane, or `base` (the rear at the
    /// lane's start), `free`, …
    pub depart_pos: &'a str,
    /// Departure speed: m/s, or `max`, `desired`, …
    pub depart_speed: &'a str,
    /// Arrival position of the front bumper on the route's last edge: metres, or `max` (its end).
    pub arrival_pos: &'a str,
}

/// One TraCI command of a batch ([`crate::Sumo::batch`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request<'a> {
    /// Read a variable of a vehicle; replies with a number, a position or a text.
    Vehicle {
        /// The vehicle.
        vehicle: &'a str,
        /// The variable.
        var: VehicleVar,
    },
    /// The ids of the vehicles in the network (0xa4, variable 0x00); replies with texts.
    VehicleIds,
    /// The simulation time in seconds (0xab, variable 0x66); replies with a number.
    Time,
    /// Teleport a vehicle; see [`MoveToXy`].
    MoveToXy(MoveToXy<'a>),
    /// Hold a vehicle at a speed in m/s; a negative speed hands it back to its driver model
    /// (0xc4, variable 0x40).
    SetSpeed {
        /// The vehicle.
        vehicle: &'a str,
        /// The speed in m/s.
        mps: f64,
    },
    /// Cap a vehicle's speed in m/s (0xc4, variable 0x41; the vehicle gets a type of its own).
    SetMaxSpeed {
        /// The vehicle.
        vehicle: &'a str,
        /// The cap in m/s.
        mps: f64,
    },
    /// SUMO's speed mode bit set of a vehicle (0xc4, variable 0xb3).
    SetSpeedMode {
        /// The vehicle.
        vehicle: &'a str,
        /// The bit set (31: every check, 0: none).
        mode: i32,
    },
    /// SUMO's lane change mode bit set of a vehicle (0xc4, variable 0xb6).
    SetLaneChangeMode {
        /// The vehicle.
        vehicle: &'a str,
        /// The bit set (1621: SUMO's default, 0: no lane change of its own).
        mode: i32,
    },
    /// Define a route by its edges (0xc6, variable 0x80).
    AddRoute {
        /// The new route's id.
        id: &'a str,
        /// Its edges, in order (normal edges only).
        edges: &'a [String],
    },
    /// Add a vehicle; see [`NewVehicle`].
    AddVehicle(NewVehicle<'a>),
}

impl Request<'_> {
    /// The command and the object it addresses, for messages.
    pub fn describe(&self) -> String {
        match self {
            Self::Vehicle { vehicle, var } => format!("vehicle.{}('{vehicle}')", var.name()),
            Self::VehicleIds => "vehicle.getIDList()".to_owned(),
            Self::Time => "simulation.getTime()".to_owned(),
            Self::MoveToXy(m) => format!(
                "vehicle.moveToXY('{}', edge '{}', lane {}, x {}, y {}, angle {}, keepRoute {})",
                m.vehicle, m.edge, m.lane, m.x, m.y, m.angle_deg, m.keep_route
            ),
            Self::SetSpeed { vehicle, mps } => format!("vehicle.setSpeed('{vehicle}', {mps})"),
            Self::SetMaxSpeed { vehicle, mps } => format!("vehicle.setMaxSpeed('{vehicle}', {mps})"),
            Self::SetSpeedMode { vehicle, mode } => {
                format!("vehicle.setSpeedMode('{vehicle}', {mode})")
            }
            Self::SetLaneChangeMode { vehicle, mode } => {
                format!("vehicle.setLaneChangeMode('{vehicle}', {mode})")
            }
            Self::AddRoute { id, edges } => format!("route.add('{id}', {edges:?})"),
            Self::AddVehicle(v) => format!("vehicle.add('{}', route '{}')", v.id, v.route),
        }
    }
}

/// SUMO's reply to one [`Request`].
#[derive(Debug, Clone, PartialEq)]
pub enum Reply {
    /// A command that changes state succeeded.
    Done,
    /// A number (a double on the wire).
    Number(f64),
    /// A position `[x, y]` in metres.
    Position([f64; 2]),
    /// A text (an id).
    Text(String),
    /// A list of texts (ids).
    Texts(Vec<String>),
}

impl Reply {
    /// The number, if this is one.
    pub fn number(&self) -> Option<f64> {
        match self {
            Self::Number(v) => Some(*v),
            _ => None,
        }
    }

    /// The position, if this is one.
    pub fn position(&self) -> Option<[f64; 2]> {
        match self {
            Self::Position(p) => Some(*p),
            _ => None,
        }
    }

    /// The text, if this is one.
    pub fn text(&self) -> Option<&str> {
        match self {
            Self::Text(t) => Some(t),
            _ => None,
        }
    }
}

/// TraCI's angle in degrees (0 = north, clockwise) of a heading in radians (0 = east, +y = π/2,
/// counter-clockwise), in `[0, 360)`.
pub fn traci_angle_deg(heading_rad: f64) -> f64 {
    (90.0 - heading_rad.to_degrees()).rem_euclid(360.0)
}

/// The heading in radians (0 = east, counter-clockwise, in `(-π, π]`) of TraCI's angle in degrees.
pub fn heading_rad(traci_angle_deg: f64) -> f64 {
    crate::geometry::wrap_angle((90.0 - traci_angle_deg).to_radians())
}
