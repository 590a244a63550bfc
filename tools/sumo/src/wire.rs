//! TraCI's byte format, without IO: messages are built in and decoded from byte buffers.
//!
//! A message is a big-endian `u32` length (counting itself) followed by commands. A command is a
//! `u8` length (counting itself and the id) and a `u8` id, or, when longer than 255 bytes, a zero
//! byte, a `u32` length (counting the five length bytes) and the id; then its content. SUMO
//! answers every command with a status command (same id, a result byte, a description string),
//! followed for *get* commands by a response command (id + 0x10: variable, object id, value type,
//! value). Strings are a `u32` byte count and the bytes; integers and doubles are big-endian.

use crate::SumoError;
use crate::traci::{Reply, Request};

/// The largest message this client reads or writes (64 MiB); a length beyond it is an error,
/// never an allocation.
pub(crate) const MAX_MESSAGE_BYTES: usize = 64 << 20;
/// The oldest TraCI API version this client speaks (SUMO 1.28 reports 22).
pub(crate) const MIN_API_VERSION: i32 = 21;

pub(crate) const CMD_GETVERSION: u8 = 0x00;
pub(crate) const CMD_LOAD: u8 = 0x01;
pub(crate) const CMD_SIMSTEP: u8 = 0x02;
pub(crate) const CMD_CLOSE: u8 = 0x7f;
const CMD_GET_VEHICLE_VARIABLE: u8 = 0xa4;
const CMD_GET_SIM_VARIABLE: u8 = 0xab;
const CMD_SET_VEHICLE_VARIABLE: u8 = 0xc4;
const CMD_SET_ROUTE_VARIABLE: u8 = 0xc6;
/// A get command's response id is its own plus this.
const RESPONSE_OFFSET: u8 = 0x10;

const ID_LIST: u8 = 0x00;
const VAR_TIME: u8 = 0x66;
const VAR_SPEED: u8 = 0x40;
const VAR_MAXSPEED: u8 = 0x41;
const VAR_SPEEDSETMODE: u8 = 0xb3;
const MOVE_TO_XY: u8 = 0xb4;
const VAR_LANECHANGE_MODE: u8 = 0xb6;
const ADD: u8 = 0x80;
const ADD_FULL: u8 = 0x85;

pub(crate) const POSITION_2D: u8 = 0x01;
const TYPE_BYTE: u8 = 0x08;
const TYPE_INTEGER: u8 = 0x09;
pub(crate) const TYPE_DOUBLE: u8 = 0x0b;
pub(crate) const TYPE_STRING: u8 = 0x0c;
const TYPE_STRINGLIST: u8 = 0x0e;
const TYPE_COMPOUND: u8 = 0x0f;

const RTYPE_OK: u8 = 0x00;
const RTYPE_NOTIMPLEMENTED: u8 = 0x01;
const RTYPE_ERR: u8 = 0xff;

// ---------------------------------------------------------------------------------------------
// Encoding

/// Starts a message in `buf` (cleared): a length placeholder.
pub(crate) fn begin(buf: &mut Vec<u8>) {
    buf.clear();
    buf.extend_from_slice(&[0; 4]);
}

/// Ends the message begun in `buf`: writes its length, or fails when it is over the bound.
pub(crate) fn finish(buf: &mut [u8]) -> Result<(), SumoError> {
    let len = buf.len();
    let field = u32::try_from(len).ok().filter(|_| len <= MAX_MESSAGE_BYTES).ok_or_else(|| {
        SumoError::protocol("outgoing message length", format!("{len} bytes, over the bound of {MAX_MESSAGE_BYTES}"))
    })?;
    if let Some(head) = buf.get_mut(..4) {
        head.copy_from_slice(&field.to_be_bytes());
    }
    Ok(())
}

/// Appends command `id` with the content `body` writes, in the short or the extended form.
fn command(buf: &mut Vec<u8>, id: u8, body: impl FnOnce(&mut Vec<u8>)) {
    let start = buf.len();
    buf.extend_from_slice(&[0, id]);
    body(buf);
    let len = buf.len() - start;
    match (u8::try_from(len), buf.get_mut(start)) {
        (Ok(short), Some(slot)) => *slot = short,
        // Extended form: 0, then the length counting 1 + 4 + 1 + content, then the id.
        _ => {
            let extended = u32::try_from(len + 4).unwrap_or(u32::MAX);
            let at = start + 1;
            buf.splice(at..at, extended.to_be_bytes());
        }
    }
}

fn put_str(buf: &mut Vec<u8>, s: &str) {
    // Beyond u32 the message is over MAX_MESSAGE_BYTES anyway: `finish` refuses it.
    buf.extend_from_slice(&u32::try_from(s.len()).unwrap_or(u32::MAX).to_be_bytes());
    buf.extend_from_slice(s.as_bytes());
}

fn put_typed_str(buf: &mut Vec<u8>, s: &str) {
    buf.push(TYPE_STRING);
    put_str(buf, s);
}

fn put_typed_i32(buf: &mut Vec<u8>, v: i32) {
    buf.push(TYPE_INTEGER);
    buf.extend_from_slice(&v.to_be_bytes());
}

fn put_typed_f64(buf: &mut Vec<u8>, v: f64) {
    buf.push(TYPE_DOUBLE);
    buf.extend_from_slice(&v.to_be_bytes());
}

fn put_count(buf: &mut Vec<u8>, n: usize) {
    buf.extend_from_slice(&u32::try_from(n).unwrap_or(u32::MAX).to_be_bytes());
}

fn put_string_list<S: AsRef<str>>(buf: &mut Vec<u8>, items: &[S]) {
    buf.push(TYPE_STRINGLIST);
    put_count(buf, items.len());
    for s in items {
        put_str(buf, s.as_ref());
    }
}

fn put_compound(buf: &mut Vec<u8>, n: usize) {
    buf.push(TYPE_COMPOUND);
    put_count(buf, n);
}

/// Appends a *set* command: variable, object id, then the typed value `value` writes.
fn set(buf: &mut Vec<u8>, cmd: u8, var: u8, object: &str, value: impl FnOnce(&mut Vec<u8>)) {
    command(buf, cmd, |b| {
        b.push(var);
        put_str(b, object);
        value(b);
    });
}

/// Appends a *get* command: variable and object id.
fn get(buf: &mut Vec<u8>, cmd: u8, var: u8, object: &str) {
    command(buf, cmd, |b| {
        b.push(var);
        put_str(b, object);
    });
}

/// Appends the command of `req`.
pub(crate) fn encode(buf: &mut Vec<u8>, req: &Request<'_>) {
    match *req {
        Request::Vehicle { vehicle, var } => get(buf, CMD_GET_VEHICLE_VARIABLE, var.id(), vehicle),
        Request::VehicleIds => get(buf, CMD_GET_VEHICLE_VARIABLE, ID_LIST, ""),
        Request::Time => get(buf, CMD_GET_SIM_VARIABLE, VAR_TIME, ""),
        Request::MoveToXy(m) => set(buf, CMD_SET_VEHICLE_VARIABLE, MOVE_TO_XY, m.vehicle, |b| {
            put_compound(b, 6);
            put_typed_str(b, m.edge);
            put_typed_i32(b, m.lane);
            put_typed_f64(b, m.x);
            put_typed_f64(b, m.y);
            put_typed_f64(b, m.angle_deg);
            b.extend_from_slice(&[TYPE_BYTE, m.keep_route]);
        }),
        Request::SetSpeed { vehicle, mps } => {
            set(buf, CMD_SET_VEHICLE_VARIABLE, VAR_SPEED, vehicle, |b| put_typed_f64(b, mps));
        }
        Request::SetMaxSpeed { vehicle, mps } => {
            set(buf, CMD_SET_VEHICLE_VARIABLE, VAR_MAXSPEED, vehicle, |b| put_typed_f64(b, mps));
        }
        Request::SetSpeedMode { vehicle, mode } => {
            set(buf, CMD_SET_VEHICLE_VARIABLE, VAR_SPEEDSETMODE, vehicle, |b| put_typed_i32(b, mode));
        }
        Request::SetLaneChangeMode { vehicle, mode } => {
            set(buf, CMD_SET_VEHICLE_VARIABLE, VAR_LANECHANGE_MODE, vehicle, |b| {
                put_typed_i32(b, mode);
            });
        }
        Request::AddRoute { id, edges } => {
            set(buf, CMD_SET_ROUTE_VARIABLE, ADD, id, |b| put_string_list(b, edges));
        }
        Request::AddVehicle(v) => set(buf, CMD_SET_VEHICLE_VARIABLE, ADD_FULL, v.id, |b| {
            put_compound(b, 14);
            let strings = [
                v.route,
                v.vehicle_type,
                v.depart,
                v.depart_lane,
                v.depart_pos,
                v.depart_speed,
                "current", // arrivalLane
                v.arrival_pos,
                "current", // arrivalSpeed
                "",        // fromTaz
                "",        // toTaz
                "",        // line
            ];
            for s in strings {
                put_typed_str(b, s);
            }
            put_typed_i32(b, 0); // personCapacity
            put_typed_i32(b, 0); // personNumber
        }),
    }
}

/// Appends *get version* (0x00).
pub(crate) fn encode_version(buf: &mut Vec<u8>) {
    command(buf, CMD_GETVERSION, |_| {});
}

/// Appends *simulation step* (0x02) to `target_s` (0: exactly one step), a raw double.
pub(crate) fn encode_step(buf: &mut Vec<u8>, target_s: f64) {
    command(buf, CMD_SIMSTEP, |b| b.extend_from_slice(&target_s.to_be_bytes()));
}

/// Appends *load* (0x01): SUMO's command line options as a string list.
pub(crate) fn encode_load(buf: &mut Vec<u8>, args: &[String]) {
    command(buf, CMD_LOAD, |b| put_string_list(b, args));
}

/// Appends *close* (0x7f).
pub(crate) fn encode_close(buf: &mut Vec<u8>) {
    command(buf, CMD_CLOSE, |_| {});
}

// ---------------------------------------------------------------------------------------------
// Decoding

/// The content length of a message whose 4-byte header is `header`, checked against the bounds.
pub(crate) fn body_len(header: [u8; 4]) -> Result<usize, SumoError> {
    let total = u32::from_be_bytes(header) as usize;
    if !(4..=MAX_MESSAGE_BYTES).contains(&total) {
        return Err(SumoError::protocol("message length", format!("{total} bytes, outside 4..={MAX_MESSAGE_BYTES}")));
    }
    Ok(total - 4)
}

/// A cursor over a message's content; every read is bounds-checked.
struct Reader<'m> {
    msg: &'m [u8],
    pos: usize,
}

impl<'m> Reader<'m> {
    fn take(&mut self, n: usize, field: &'static str) -> Result<&'m [u8], SumoError> {
        let bytes = self.pos.checked_add(n).and_then(|end| self.msg.get(self.pos..end));
        let bytes = bytes.ok_or_else(|| {
            SumoError::protocol(
                field,
                format!("needs {n} bytes at offset {}, the message has {}", self.pos, self.msg.len()),
            )
        })?;
        self.pos += n;
        Ok(bytes)
    }

    fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], SumoError> {
        let mut out = [0; N];
        out.copy_from_slice(self.take(N, field)?);
        Ok(out)
    }

    fn u8(&mut self, field: &'static str) -> Result<u8, SumoError> {
        Ok(u8::from_be_bytes(self.array(field)?))
    }

    fn i32(&mut self, field: &'static str) -> Result<i32, SumoError> {
        Ok(i32::from_be_bytes(self.array(field)?))
    }

    fn f64(&mut self, field: &'static str) -> Result<f64, SumoError> {
        Ok(f64::from_be_bytes(self.array(field)?))
    }

    /// A count or length field: non-negative and, at `min_bytes` per item, within the message.
    fn count(&mut self, field: &'static str, min_bytes: usize) -> Result<usize, SumoError> {
        let n = self.i32(field)?;
        let left = self.msg.len() - self.pos;
        match usize::try_from(n) {
            Ok(n) if n.saturating_mul(min_bytes) <= left => Ok(n),
            _ => Err(SumoError::protocol(field, format!("{n} items of at least {min_bytes} bytes, {left} bytes left"))),
        }
    }

    fn string(&mut self, field: &'static str) -> Result<String, SumoError> {
        let n = self.count(field, 1)?;
        Ok(String::from_utf8_lossy(self.take(n, field)?).into_owned())
    }

    fn expect_type(&mut self, want: u8, field: &'static str) -> Result<(), SumoError> {
        match self.u8(field)? {
            got if got == want => Ok(()),
            got => Err(SumoError::protocol(field, format!("value type 0x{got:02x}, expected 0x{want:02x}"))),
        }
    }

    /// The next command's header: its id and the offset where it ends.
    fn command(&mut self, field: &'static str) -> Result<(u8, usize), SumoError> {
        let start = self.pos;
        let (len, header) = match self.u8(field)? {
            0 => (self.count(field, 0)?, 6),
            short => (usize::from(short), 2),
        };
        let end = start + len;
        if len < header || end > self.msg.len() {
            return Err(SumoError::protocol(
                field,
                format!(
                    "command length {len} at offset {start}: below {header} or beyond the message's {} bytes",
                    self.msg.len()
                ),
            ));
        }
        Ok((self.u8(field)?, end))
    }

    fn expect_end(&self, end: usize, field: &'static str) -> Result<(), SumoError> {
        if self.pos == end {
            return Ok(());
        }
        Err(SumoError::protocol(field, format!("the command ends at offset {end}, its content at {}", self.pos)))
    }

    /// The status of command `cmd`: `Ok(Err(description))` when SUMO refused it.
    fn status(&mut self, cmd: u8) -> Result<Result<(), String>, SumoError> {
        let (id, end) = self.command("status command")?;
        if id != cmd {
            return Err(SumoError::protocol("status command id", format!("0x{id:02x}, expected 0x{cmd:02x}")));
        }
        let result = self.u8("status result")?;
        let description = self.string("status description")?;
        self.expect_end(end, "status command")?;
        match result {
            RTYPE_OK => Ok(Ok(())),
            RTYPE_ERR => Ok(Err(description)),
            RTYPE_NOTIMPLEMENTED => Ok(Err(format!("not implemented: {description}"))),
            other => Err(SumoError::protocol("status result", format!("0x{other:02x}"))),
        }
    }

    fn finish(&self) -> Result<(), SumoError> {
        match self.msg.len() - self.pos {
            0 => Ok(()),
            extra => Err(SumoError::protocol("message length", format!("{extra} bytes after the last reply"))),
        }
    }
}

/// The command id of `req` and, for a *get*, the response's variable, object and value type.
fn shape<'r>(req: &Request<'r>) -> (u8, Option<(u8, &'r str, u8)>) {
    match *req {
        Request::Vehicle { vehicle, var } => (CMD_GET_VEHICLE_VARIABLE, Some((var.id(), vehicle, var.value_type()))),
        Request::VehicleIds => (CMD_GET_VEHICLE_VARIABLE, Some((ID_LIST, "", TYPE_STRINGLIST))),
        Request::Time => (CMD_GET_SIM_VARIABLE, Some((VAR_TIME, "", TYPE_DOUBLE))),
        Request::AddRoute { .. } => (CMD_SET_ROUTE_VARIABLE, None),
        Request::MoveToXy(_)
        | Request::SetSpeed { .. }
        | Request::SetMaxSpeed { .. }
        | Request::SetSpeedMode { .. }
        | Request::SetLaneChangeMode { .. }
        | Request::AddVehicle(_) => (CMD_SET_VEHICLE_VARIABLE, None),
    }
}

fn value(r: &mut Reader<'_>, value_type: u8) -> Result<Reply, SumoError> {
    r.expect_type(value_type, "response value type")?;
    Ok(match value_type {
        TYPE_DOUBLE => Reply::Number(r.f64("double value")?),
        POSITION_2D => Reply::Position([r.f64("position x")?, r.f64("position y")?]),
        TYPE_STRING => Reply::Text(r.string("string value")?),
        _ => {
            let n = r.count("string list count", 4)?;
            let mut items = Vec::with_capacity(n);
            for _ in 0..n {
                items.push(r.string("string list item")?);
            }
            Reply::Texts(items)
        }
    })
}

/// Decodes the replies to `requests` from a message's content `msg` into `out` (cleared). A
/// refused command becomes [`SumoError::Command`].
pub(crate) fn decode_replies(msg: &[u8], requests: &[Request<'_>], out: &mut Vec<Reply>) -> Result<(), SumoError> {
    out.clear();
    let mut r = Reader { msg, pos: 0 };
    for req in requests {
        let (cmd, response) = shape(req);
        if let Err(message) = r.status(cmd)? {
            return Err(SumoError::Command { command: req.describe(), message });
        }
        let Some((var, object, value_type)) = response else {
            out.push(Reply::Done);
            continue;
        };
        let (id, end) = r.command("response command")?;
        let want = cmd.wrapping_add(RESPONSE_OFFSET);
        if id != want {
            return Err(SumoError::protocol("response command id", format!("0x{id:02x}, expected 0x{want:02x}")));
        }
        let got_var = r.u8("response variable")?;
        if got_var != var {
            return Err(SumoError::protocol("response variable", format!("0x{got_var:02x}, expected 0x{var:02x}")));
        }
        let got_object = r.string("response object id")?;
        if got_object != object {
            return Err(SumoError::protocol("response object id", format!("'{got_object}', expected '{object}'")));
        }
        out.push(value(&mut r, value_type)?);
        r.expect_end(end, "response command")?;
    }
    r.finish()
}

/// Decodes the reply to a command that answers with its status only (load, close).
pub(crate) fn decode_status(msg: &[u8], cmd: u8, command: &str) -> Result<(), SumoError> {
    let mut r = Reader { msg, pos: 0 };
    if let Err(message) = r.status(cmd)? {
        return Err(SumoError::Command { command: command.to_owned(), message });
    }
    r.finish()
}

/// Decodes the reply to *simulation step*: the status, then the count of subscription results
/// (this client subscribes to nothing; any results are skipped).
pub(crate) fn decode_step(msg: &[u8]) -> Result<(), SumoError> {
    let mut r = Reader { msg, pos: 0 };
    if let Err(message) = r.status(CMD_SIMSTEP)? {
        return Err(SumoError::Command { command: "simulationStep()".to_owned(), message });
    }
    r.i32("subscription result count")?;
    Ok(())
}

/// Decodes the reply to *get version*: the API version and SUMO's identifier.
pub(crate) fn decode_version(msg: &[u8]) -> Result<(i32, String), SumoError> {
    let mut r = Reader { msg, pos: 0 };
    if let Err(message) = r.status(CMD_GETVERSION)? {
        return Err(SumoError::Command { command: "getVersion()".to_owned(), message });
    }
    let (id, end) = r.command("version response")?;
    if id != CMD_GETVERSION {
        return Err(SumoError::protocol("version response id", format!("0x{id:02x}, expected 0x{CMD_GETVERSION:02x}")));
    }
    let api = r.i32("API version")?;
    let identifier = r.string("server identifier")?;
    r.expect_end(end, "version response")?;
    r.finish()?;
    Ok((api, identifier))
}

#[cfg(test)]
mod tests;
