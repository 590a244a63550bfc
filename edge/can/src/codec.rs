//! Typed messages of `config/can/bv.dbc` over the frame types that dbc-codegen generates from it.
//!
//! The generated code (`crate::generated`) owns the bit layout: which bits each signal occupies,
//! the dispatch from id to message type, payload-size checks. This layer adds what the DBC only
//! describes in comments: the rolling counter and the checksum ([`crate::checksum`]), one counter
//! per id on both sides, and `f64` scaling with rounding (generated from the same DBC into
//! [`signals`]) so that encode → decode → encode is bit-exact and every range check fails NaN.

use embedded_can::{Id, StandardId};

use crate::checksum::{COUNTER_MODULUS, frame_checksum, next_counter};
use crate::generated as dbc;

/// A classic CAN 2.0A data frame as this crate sends and receives it: an 11-bit id and up to 8
/// data bytes. Plain data, no socket types.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct CanFrame {
    /// Standard (11-bit) identifier.
    pub id: u32,
    /// Number of valid bytes in `data` (DLC), 0..=8.
    pub len: u8,
    /// Payload; bytes past `len` are zero.
    pub data: [u8; 8],
}

impl CanFrame {
    /// Largest standard identifier.
    pub const MAX_STANDARD_ID: u32 = 0x7FF;

    /// A full 8-byte frame.
    pub const fn new(id: u32, data: [u8; 8]) -> Self {
        Self { id, len: 8, data }
    }

    /// The valid bytes.
    pub fn payload(&self) -> &[u8] {
        self.data.get(..usize::from(self.len.min(8))).unwrap_or(&[])
    }
}

/// Scaling and range of one DBC signal: `physical = raw · factor + offset`, valid in `[min, max]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scale {
    /// `Message.Signal` as written in the DBC.
    pub name: &'static str,
    /// Physical units per raw step.
    pub factor: f64,
    /// Physical value of raw 0.
    pub offset: f64,
    /// Smallest valid physical value.
    pub min: f64,
    /// Largest valid physical value.
    pub max: f64,
}

/// Every signal's [`Scale`] and every message's id, generated from `config/can/bv.dbc`.
pub mod signals {
    use super::Scale;
    include!(concat!(env!("OUT_DIR"), "/bv_signals.rs"));
}

/// Id of `BV_AccelCmd`.
pub const ACCEL_CMD_ID: u32 = signals::BV_ACCEL_CMD_ID;
/// Id of `BV_SteerCmd`.
pub const STEER_CMD_ID: u32 = signals::BV_STEER_CMD_ID;
/// Id of `BV_ControlState`.
pub const CONTROL_STATE_ID: u32 = signals::BV_CONTROL_STATE_ID;
/// Id of `DBW_Feedback`.
pub const DBW_FEEDBACK_ID: u32 = signals::DBW_FEEDBACK_ID;
/// Every id of the DBC, in [`Message`] order.
pub const MESSAGE_IDS: [u32; 4] = [ACCEL_CMD_ID, STEER_CMD_ID, CONTROL_STATE_ID, DBW_FEEDBACK_ID];
/// Payload length of every message, bytes.
pub const FRAME_LEN: u8 = 8;

/// Why a message could not be encoded or a frame was rejected.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum CodecError {
    /// The id is not in the DBC.
    #[error("unknown CAN id {id:#05x}")]
    UnknownId {
        /// The id.
        id: u32,
    },
    /// The frame is not 8 bytes long.
    #[error("frame {id:#05x}: length {len}, expected {expected}")]
    BadLength {
        /// The id.
        id: u32,
        /// Its length.
        len: u8,
        /// The DBC's length.
        expected: u8,
    },
    /// The checksum byte does not match the frame.
    #[error("frame {id:#05x}: checksum {got:#04x}, expected {expected:#04x}")]
    BadChecksum {
        /// The id.
        id: u32,
        /// Checksum in the frame.
        got: u8,
        /// Checksum computed over the frame.
        expected: u8,
    },
    /// The rolling counter repeated or skipped.
    #[error("frame {id:#05x}: counter {got}, expected {expected} (repeated or skipped frame)")]
    BadCounter {
        /// The id.
        id: u32,
        /// Counter in the frame.
        got: u8,
        /// The previous counter of this id plus one.
        expected: u8,
    },
    /// A signal value outside its DBC range.
    #[error("signal {signal}: {value} outside [{min}, {max}]")]
    OutOfRange {
        /// `Message.Signal`.
        signal: &'static str,
        /// The value.
        value: f64,
        /// Range minimum.
        min: f64,
        /// Range maximum.
        max: f64,
    },
    /// A signal value that is NaN or infinite.
    #[error("signal {signal}: non-finite value {value}")]
    NonFinite {
        /// `Message.Signal`.
        signal: &'static str,
        /// The value.
        value: f64,
    },
}

impl Scale {
    fn raw_bound(self, physical: f64) -> i64 {
        ((physical - self.offset) / self.factor).round() as i64
    }

    fn out_of_range(self, value: f64) -> CodecError {
        CodecError::OutOfRange { signal: self.name, value, min: self.min, max: self.max }
    }

    /// The raw value of `value`, rounded to the nearest step; NaN, infinities and values outside
    /// `[min, max]` are errors.
    pub fn to_raw(self, value: f64) -> Result<i64, CodecError> {
        if !value.is_finite() {
            return Err(CodecError::NonFinite { signal: self.name, value });
        }
        if !(value >= self.min && value <= self.max) {
            return Err(self.out_of_range(value));
        }
        let raw = ((value - self.offset) / self.factor).round() as i64;
        Ok(raw.clamp(self.raw_bound(self.min), self.raw_bound(self.max)))
    }

    /// The physical value of `raw`; raw values outside the range are errors.
    pub fn to_physical(self, raw: i64) -> Result<f64, CodecError> {
        let value = raw as f64 * self.factor + self.offset;
        if raw < self.raw_bound(self.min) || raw > self.raw_bound(self.max) {
            return Err(self.out_of_range(value));
        }
        // Within one ulp of the range: clamp so that the value encodes again.
        Ok(value.clamp(self.min, self.max))
    }

    fn to_raw_i16(self, value: f64) -> Result<i16, CodecError> {
        i16::try_from(self.to_raw(value)?).map_err(|_| self.out_of_range(value))
    }

    fn to_raw_u8(self, value: u8) -> Result<u8, CodecError> {
        let value = f64::from(value);
        u8::try_from(self.to_raw(value)?).map_err(|_| self.out_of_range(value))
    }

    fn to_u8(self, raw: u8) -> Result<u8, CodecError> {
        self.to_physical(i64::from(raw))?;
        Ok(raw)
    }
}

/// `BV_AccelCmd`: the longitudinal request.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AccelCmd {
    /// Requested acceleration, m/s² (braking negative).
    pub accel_mps2: f64,
    /// Execute the request.
    pub enable: bool,
}

/// `BV_SteerCmd`: the lateral request.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SteerCmd {
    /// Requested road-wheel angle, rad (left positive).
    pub steer_rad: f64,
    /// Execute the request.
    pub enable: bool,
}

/// `BV_ControlState`: the gate's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ControlState {
    /// Gate state code: 0 disengaged, 1 engaged, 2 minimal-risk stop, 3 fault
    /// (the codes of [`v2t_wire::GateState`]).
    pub gate_state: u8,
    /// The gate wants the DBW in automatic mode.
    pub engage_request: bool,
    /// Free-running transmit-cycle counter.
    pub heartbeat: u8,
}

/// `DBW_Feedback`: what the drive-by-wire ECU measures.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DbwFeedback {
    /// Mean wheel speed, m/s.
    pub wheel_speed_mps: f64,
    /// Yaw rate, rad/s (counter-clockwise positive).
    pub yaw_rate_radps: f64,
    /// Road-wheel angle, rad (left positive).
    pub steer_rad: f64,
    /// DBW mode code: 0 manual, 1 auto, 2 override, 3 fault (`v2t_wire::DbwMode`).
    pub mode: u8,
}

/// Any message of the DBC.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Message {
    /// `BV_AccelCmd`.
    Accel(AccelCmd),
    /// `BV_SteerCmd`.
    Steer(SteerCmd),
    /// `BV_ControlState`.
    Control(ControlState),
    /// `DBW_Feedback`.
    Feedback(DbwFeedback),
}

impl Message {
    /// The CAN id that carries this message.
    pub const fn id(&self) -> u32 {
        match self {
            Self::Accel(_) => ACCEL_CMD_ID,
            Self::Steer(_) => STEER_CMD_ID,
            Self::Control(_) => CONTROL_STATE_ID,
            Self::Feedback(_) => DBW_FEEDBACK_ID,
        }
    }
}

/// Index of `id` in [`MESSAGE_IDS`].
fn slot(id: u32) -> Option<usize> {
    MESSAGE_IDS.iter().position(|&known| known == id)
}

/// Counter and checksum access shared by the generated frame types.
trait Protected: Sized {
    const ID: u32;
    fn from_payload(payload: &[u8]) -> Result<Self, dbc::CanError>;
    fn raw_payload(&self) -> [u8; 8];
    fn counter(&self) -> u8;
    fn checksum(&self) -> u8;
    fn set_counter(&mut self, counter: u8) -> Result<(), dbc::CanError>;
    fn set_checksum(&mut self, checksum: u8) -> Result<(), dbc::CanError>;

    /// An all-zero frame of this type.
    fn zeroed() -> Result<Self, CodecError> {
        Self::from_payload(&[0; 8]).map_err(|e| generated_error(Self::ID, e))
    }

    /// Writes `counter`, then the checksum over everything else; returns the payload.
    fn seal(mut self, counter: u8) -> Result<[u8; 8], CodecError> {
        self.set_counter(counter).map_err(|e| generated_error(Self::ID, e))?;
        let checksum = frame_checksum(Self::ID, &self.raw_payload());
        self.set_checksum(checksum).map_err(|e| generated_error(Self::ID, e))?;
        Ok(self.raw_payload())
    }
}

macro_rules! protected {
    ($($ty:ty => $id:expr),* $(,)?) => {$(
        impl Protected for $ty {
            const ID: u32 = $id;
            fn from_payload(payload: &[u8]) -> Result<Self, dbc::CanError> {
                Self::try_from(payload)
            }
            fn raw_payload(&self) -> [u8; 8] {
                *self.raw()
            }
            fn counter(&self) -> u8 {
                self.counter_raw_val()
            }
            fn checksum(&self) -> u8 {
                self.checksum_raw_val()
            }
            fn set_counter(&mut self, counter: u8) -> Result<(), dbc::CanError> {
                <$ty>::set_counter(self, counter)
            }
            fn set_checksum(&mut self, checksum: u8) -> Result<(), dbc::CanError> {
                <$ty>::set_checksum(self, checksum)
            }
        }
    )*};
}

protected! {
    dbc::BvAccelCmd => ACCEL_CMD_ID,
    dbc::BvSteerCmd => STEER_CMD_ID,
    dbc::BvControlState => CONTROL_STATE_ID,
    dbc::DbwFeedback => DBW_FEEDBACK_ID,
}

/// Maps an error of the generated code to ours.
fn generated_error(id: u32, e: dbc::CanError) -> CodecError {
    match e {
        dbc::CanError::InvalidPayloadSize => CodecError::BadLength { id, len: 0, expected: FRAME_LEN },
        // The generated setters are only called with values this module range-checked before.
        dbc::CanError::ParameterOutOfRange { .. } | dbc::CanError::InvalidMultiplexor { .. } => {
            CodecError::OutOfRange { signal: "counter/checksum", value: f64::NAN, min: 0.0, max: 255.0 }
        }
        dbc::CanError::UnknownMessageId(_) => CodecError::UnknownId { id },
    }
}

fn bool_bit(b: bool) -> u8 {
    u8::from(b)
}

/// The payload of `msg` with `counter` and its checksum.
fn payload_of(msg: &Message, counter: u8) -> Result<[u8; 8], CodecError> {
    use signals as s;
    match msg {
        Message::Accel(m) => {
            let mut f = dbc::BvAccelCmd::zeroed()?;
            f.set_accel_request_raw_val(s::BV_ACCEL_CMD_ACCEL_REQUEST.to_raw_i16(m.accel_mps2)?);
            f.set_accel_enable_raw_val(bool_bit(m.enable));
            f.seal(counter)
        }
        Message::Steer(m) => {
            let mut f = dbc::BvSteerCmd::zeroed()?;
            f.set_steer_request_raw_val(s::BV_STEER_CMD_STEER_REQUEST.to_raw_i16(m.steer_rad)?);
            f.set_steer_enable_raw_val(bool_bit(m.enable));
            f.seal(counter)
        }
        Message::Control(m) => {
            let mut f = dbc::BvControlState::zeroed()?;
            f.set_gate_state_raw_val(s::BV_CONTROL_STATE_GATE_STATE.to_raw_u8(m.gate_state)?);
            f.set_engage_request_raw_val(bool_bit(m.engage_request));
            f.set_heartbeat_raw_val(s::BV_CONTROL_STATE_HEARTBEAT.to_raw_u8(m.heartbeat)?);
            f.seal(counter)
        }
        Message::Feedback(m) => {
            let mut f = dbc::DbwFeedback::zeroed()?;
            f.set_wheel_speed_raw_val(s::DBW_FEEDBACK_WHEEL_SPEED.to_raw_i16(m.wheel_speed_mps)?);
            f.set_yaw_rate_raw_val(s::DBW_FEEDBACK_YAW_RATE.to_raw_i16(m.yaw_rate_radps)?);
            f.set_steer_angle_raw_val(s::DBW_FEEDBACK_STEER_ANGLE.to_raw_i16(m.steer_rad)?);
            f.set_mode_raw_val(s::DBW_FEEDBACK_MODE.to_raw_u8(m.mode)?);
            f.seal(counter)
        }
    }
}

/// Encodes messages into frames, with one rolling counter per id (starting at 0).
#[derive(Debug, Clone, Default)]
pub struct Encoder {
    counters: [u8; 4],
}

impl Encoder {
    /// The frame that carries `msg`. A message that cannot be encoded (a value out of range or
    /// not finite) is an error and does not advance the counter.
    pub fn encode(&mut self, msg: &Message) -> Result<CanFrame, CodecError> {
        let id = msg.id();
        let counter = self.next_counter(id).unwrap_or(0);
        let data = payload_of(msg, counter)?;
        if let Some(c) = slot(id).and_then(|i| self.counters.get_mut(i)) {
            *c = next_counter(counter);
        }
        Ok(CanFrame::new(id, data))
    }

    /// `BV_AccelCmd` frame.
    pub fn accel(&mut self, m: &AccelCmd) -> Result<CanFrame, CodecError> {
        self.encode(&Message::Accel(*m))
    }

    /// `BV_SteerCmd` frame.
    pub fn steer(&mut self, m: &SteerCmd) -> Result<CanFrame, CodecError> {
        self.encode(&Message::Steer(*m))
    }

    /// `BV_ControlState` frame.
    pub fn control(&mut self, m: &ControlState) -> Result<CanFrame, CodecError> {
        self.encode(&Message::Control(*m))
    }

    /// `DBW_Feedback` frame.
    pub fn feedback(&mut self, m: &DbwFeedback) -> Result<CanFrame, CodecError> {
        self.encode(&Message::Feedback(*m))
    }

    /// The counter the next frame of `id` will carry (`None` for an unknown id).
    pub fn next_counter(&self, id: u32) -> Option<u8> {
        slot(id).and_then(|i| self.counters.get(i)).copied()
    }
}

/// Rolling-counter supervision, one counter per id: the first frame of an id is accepted with any
/// counter; after that each frame must carry the previous counter plus one (mod 16). A repeated
/// or skipped counter is rejected, and the check resynchronises on it, so one lost frame costs
/// one rejected frame.
#[derive(Debug, Clone, Default)]
pub struct CounterCheck {
    last: [Option<u8>; 4],
}

impl CounterCheck {
    /// Checks `counter` of a frame of `id` and remembers it.
    pub fn check(&mut self, id: u32, counter: u8) -> Result<(), CodecError> {
        let last = slot(id).and_then(|i| self.last.get_mut(i)).ok_or(CodecError::UnknownId { id })?;
        let counter = counter % COUNTER_MODULUS;
        let previous = last.replace(counter);
        match previous {
            Some(p) if next_counter(p) != counter => {
                Err(CodecError::BadCounter { id, got: counter, expected: next_counter(p) })
            }
            _ => Ok(()),
        }
    }

    /// Forgets every counter (after a bus restart): the next frame of each id is accepted.
    pub fn reset(&mut self) {
        self.last = [None; 4];
    }
}

/// Decodes frames into messages, verifying length, checksum, counter and ranges.
#[derive(Debug, Clone, Default)]
pub struct Decoder {
    counters: CounterCheck,
}

impl Decoder {
    /// The message in `frame`. Checks, in order: known id, length 8, checksum, counter (per id),
    /// signal ranges. A frame with a bad checksum leaves the counter state untouched.
    pub fn decode(&mut self, frame: &CanFrame) -> Result<Message, CodecError> {
        let id = frame.id;
        let std_id = u16::try_from(id).ok().and_then(StandardId::new).ok_or(CodecError::UnknownId { id })?;
        if slot(id).is_none() {
            return Err(CodecError::UnknownId { id });
        }
        if frame.len != FRAME_LEN {
            return Err(CodecError::BadLength { id, len: frame.len, expected: FRAME_LEN });
        }
        let frame_msg = dbc::Messages::from_can_message(Id::Standard(std_id), frame.payload())
            .map_err(|e| generated_error(id, e))?;
        let (counter, checksum) = match &frame_msg {
            dbc::Messages::BvAccelCmd(f) => (Protected::counter(f), Protected::checksum(f)),
            dbc::Messages::BvSteerCmd(f) => (Protected::counter(f), Protected::checksum(f)),
            dbc::Messages::BvControlState(f) => (Protected::counter(f), Protected::checksum(f)),
            dbc::Messages::DbwFeedback(f) => (Protected::counter(f), Protected::checksum(f)),
        };
        let expected = frame_checksum(id, &frame.data);
        if checksum != expected {
            return Err(CodecError::BadChecksum { id, got: checksum, expected });
        }
        self.counters.check(id, counter)?;
        message_of(&frame_msg)
    }

    /// Forgets the counters (see [`CounterCheck::reset`]).
    pub fn reset(&mut self) {
        self.counters.reset();
    }
}

/// The typed message of a generated frame, range-checked.
fn message_of(frame: &dbc::Messages) -> Result<Message, CodecError> {
    use signals as s;
    Ok(match frame {
        dbc::Messages::BvAccelCmd(f) => Message::Accel(AccelCmd {
            accel_mps2: s::BV_ACCEL_CMD_ACCEL_REQUEST.to_physical(f.accel_request_raw_val().into())?,
            enable: f.accel_enable_raw_val() == 1,
        }),
        dbc::Messages::BvSteerCmd(f) => Message::Steer(SteerCmd {
            steer_rad: s::BV_STEER_CMD_STEER_REQUEST.to_physical(f.steer_request_raw_val().into())?,
            enable: f.steer_enable_raw_val() == 1,
        }),
        dbc::Messages::BvControlState(f) => Message::Control(ControlState {
            gate_state: s::BV_CONTROL_STATE_GATE_STATE.to_u8(f.gate_state_raw_val())?,
            engage_request: f.engage_request_raw_val() == 1,
            heartbeat: s::BV_CONTROL_STATE_HEARTBEAT.to_u8(f.heartbeat_raw_val())?,
        }),
        dbc::Messages::DbwFeedback(f) => Message::Feedback(DbwFeedback {
            wheel_speed_mps: s::DBW_FEEDBACK_WHEEL_SPEED.to_physical(f.wheel_speed_raw_val().into())?,
            yaw_rate_radps: s::DBW_FEEDBACK_YAW_RATE.to_physical(f.yaw_rate_raw_val().into())?,
            steer_rad: s::DBW_FEEDBACK_STEER_ANGLE.to_physical(f.steer_angle_raw_val().into())?,
            mode: s::DBW_FEEDBACK_MODE.to_u8(f.mode_raw_val())?,
        }),
    })
}

#[cfg(test)]
#[path = "codec_tests.rs"]
mod tests;
