//! A running `sumo` process and its TraCI connection.

use std::io::{Read as _, Write as _};
use std::net::{Ipv4Addr, SocketAddr, TcpListener, TcpStream};
use std::path::PathBuf;
use std::process::{Child, ChildStderr, ChildStdout, Stdio};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::binaries::{command_line, tail};
use crate::traci::{MoveToXy, NewVehicle, Reply, Request, VehicleVar};
use crate::{SumoBinaries, SumoError, wire};

/// How long SUMO may take to accept the connection after it starts.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);
/// How long one reply may take before the connection counts as wedged.
const READ_TIMEOUT: Duration = Duration::from_secs(30);
/// How long `close` waits for SUMO to exit before killing it.
const EXIT_GRACE: Duration = Duration::from_secs(2);
/// How much of SUMO's output is kept for error messages, bytes.
const OUTPUT_KEPT: usize = 16 * 1024;

/// What a simulation is made of: the options of [`Sumo::start`] and [`Sumo::load`].
#[derive(Debug, Clone, PartialEq)]
pub struct StartOptions {
    /// The network (`.net.xml`).
    pub net: PathBuf,
    /// Additional files (vehicle types, …), loaded in order.
    pub additional: Vec<PathBuf>,
    /// Simulation step in seconds (> 0).
    pub step_length_s: f64,
    /// Seed of SUMO's random numbers (driver imperfection, speed factors): SUMO parses it as a
    /// 32-bit signed integer, so at most 2147483647.
    pub seed: u64,
    /// Further `sumo` options, appended as given.
    pub extra_args: Vec<String>,
}

impl StartOptions {
    /// `sumo`'s options for these, without the TraCI port: ballistic update, collisions at
    /// junctions checked and only warned about, no teleporting of stuck vehicles, no step log,
    /// no warnings.
    pub fn args(&self) -> Result<Vec<String>, SumoError> {
        if !(self.step_length_s > 0.0 && self.step_length_s.is_finite()) {
            return Err(SumoError::InvalidArgument {
                what: "step_length_s",
                problem: format!("{}: must be a finite positive number of seconds", self.step_length_s),
            });
        }
        if i32::try_from(self.seed).is_err() {
            return Err(SumoError::InvalidArgument {
                what: "seed",
                problem: format!(
                    "{}: SUMO takes seeds up to {} (fold larger ones into that range)",
                    self.seed,
                    i32::MAX
                ),
            });
        }
        let text = |p: &PathBuf, what: &'static str| {
            p.to_str().map(str::to_owned).filter(|t| !t.contains(',')).ok_or_else(|| SumoError::InvalidArgument {
                what,
                problem: format!("{}: SUMO needs UTF-8 paths without commas", p.display()),
            })
        };
        let mut args = vec!["--net-file".to_owned(), text(&self.net, "net")?];
        if !self.additional.is_empty() {
            let files = self.additional.iter().map(|p| text(p, "additional")).collect::<Result<Vec<_>, _>>()?;
            args.extend(["--additional-files".to_owned(), files.join(",")]);
        }
        let fixed = [
            ("--step-length", self.step_length_s.to_string()),
            ("--seed", self.seed.to_string()),
            ("--begin", "0".to_owned()),
            ("--no-step-log", "true".to_owned()),
            ("--no-warnings", "false".to_owned()),
            ("--collision.action", "warn".to_owned()),
            ("--collision.check-junctions", "true".to_owned()),
            ("--time-to-teleport", "-1".to_owned()),
            ("--step-method.ballistic", "true".to_owned()),
        ];
        for (flag, value) in fixed {
            args.extend([flag.to_owned(), value]);
        }
        args.extend(self.extra_args.iter().cloned());
        Ok(args)
    }
}

/// The last bytes SUMO wrote to stdout and stderr, collected by two threads so a full pipe never
/// blocks it.
#[derive(Debug)]
struct Output {
    kept: Arc<Mutex<Vec<u8>>>,
    drains: Vec<JoinHandle<()>>,
}

impl Output {
    fn capture(stdout: Option<ChildStdout>, stderr: Option<ChildStderr>) -> Self {
        let kept = Arc::new(Mutex::new(Vec::new()));
        let mut drains = Vec::new();
        let readers: [Option<Box<dyn std::io::Read + Send>>; 2] =
            [stdout.map(|s| Box::new(s) as _), stderr.map(|s| Box::new(s) as _)];
        for mut reader in readers.into_iter().flatten() {
            let kept = Arc::clone(&kept);
            drains.push(std::thread::spawn(move || {
                let mut chunk = [0u8; 4096];
                while let Ok(n @ 1..) = reader.read(&mut chunk) {
                    let mut buf = kept.lock().unwrap_or_else(PoisonError::into_inner);
                    buf.extend_from_slice(chunk.get(..n).unwrap_or_default());
                    let excess = buf.len().saturating_sub(OUTPUT_KEPT);
                    buf.drain(..excess);
                }
            }));
        }
        Self { kept, drains }
    }

    /// The last lines kept.
    fn tail(&self) -> String {
        let buf = self.kept.lock().unwrap_or_else(PoisonError::into_inner);
        tail(&String::from_utf8_lossy(&buf), 30)
    }

    /// The last lines, complete when SUMO has exited.
    fn final_tail_if_exited(&mut self, child: &mut Child) -> String {
        if matches!(child.try_wait(), Ok(Some(_))) { self.final_tail() } else { self.tail() }
    }

    /// The last lines, after SUMO exited (waits for the drains to read everything).
    fn final_tail(&mut self) -> String {
        for drain in self.drains.drain(..) {
            let _ = drain.join();
        }
        self.tail()
    }
}

/// A running `sumo` with a TraCI connection on loopback. Dropping it kills the process.
///
/// Vehicle positions, here and in SUMO, are those of the **front bumper centre**; angles are
/// TraCI's (degrees, 0 = north, clockwise; see [`crate::traci_angle_deg`]).
#[derive(Debug)]
pub struct Sumo {
    child: Child,
    stream: TcpStream,
    output: Output,
    port: u16,
    api_version: i32,
    identifier: String,
    send: Vec<u8>,
    recv: Vec<u8>,
    scratch: Vec<Reply>,
}

impl Sumo {
    /// Starts `sumo` on `opts` with TraCI on a free loopback port, connects (retrying for up to
    /// 10 s) and checks its TraCI API version (≥ 21).
    pub fn start(bins: &SumoBinaries, opts: &StartOptions) -> Result<Sumo, SumoError> {
        let port = free_port()?;
        let mut cmd = bins.command(&bins.sumo);
        cmd.args(opts.args()?)
            .args(["--remote-port".to_owned(), port.to_string()])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let line = command_line(&cmd);
        let mut child = cmd.spawn().map_err(|source| SumoError::Spawn { command: line, source })?;
        let mut output = Output::capture(child.stdout.take(), child.stderr.take());
        let stream = match connect(&mut child, port, &mut output) {
            Ok(stream) => stream,
            Err(e) => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(e);
            }
        };
        let mut sumo = Sumo {
            child,
            stream,
            output,
            port,
            api_version: 0,
            identifier: String::new(),
            send: Vec::with_capacity(1024),
            recv: Vec::with_capacity(1024),
            scratch: Vec::with_capacity(3),
        };
        // SUMO accepts the connection before it loads the network: a bad option or file shows
        // as the connection closing before the version comes back.
        wire::begin(&mut sumo.send);
        wire::encode_version(&mut sumo.send);
        if let Err(e) = sumo.roundtrip() {
            let reason = match (sumo.child.try_wait(), e) {
                (Ok(Some(status)), _) => format!("SUMO exited ({status}) before reporting its TraCI version"),
                (_, SumoError::Io { source, .. }) => {
                    format!("SUMO closed the connection before reporting its TraCI version ({source})")
                }
                (_, other) => other.to_string(),
            };
            let output_tail = sumo.output.final_tail_if_exited(&mut sumo.child);
            return Err(SumoError::Connect { port, reason, output_tail });
        }
        let (api, identifier) = wire::decode_version(&sumo.recv)?;
        if api < wire::MIN_API_VERSION {
            return Err(SumoError::ApiVersion { found: api, identifier, required: wire::MIN_API_VERSION });
        }
        sumo.api_version = api;
        sumo.identifier = identifier;
        Ok(sumo)
    }

    /// SUMO's TraCI API version (22 for SUMO 1.28).
    pub fn api_version(&self) -> i32 {
        self.api_version
    }

    /// SUMO's identifier, e.g. `SUMO v1_28_0`.
    pub fn identifier(&self) -> &str {
        &self.identifier
    }

    /// The loopback port of the TraCI connection.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// The last lines SUMO wrote to stdout and stderr.
    pub fn output_tail(&self) -> String {
        self.output.tail()
    }

    /// Restarts the simulation in this process on `opts` (TraCI *load*): time 0, no vehicles, the
    /// connection kept. One process serves many runs.
    pub fn load(&mut self, opts: &StartOptions) -> Result<(), SumoError> {
        let args = opts.args()?;
        wire::begin(&mut self.send);
        wire::encode_load(&mut self.send, &args);
        self.roundtrip()?;
        wire::decode_status(&self.recv, wire::CMD_LOAD, "load()")
    }

    /// Advances the simulation by one step (TraCI *simulation step* with target time 0).
    pub fn step(&mut self) -> Result<(), SumoError> {
        wire::begin(&mut self.send);
        wire::encode_step(&mut self.send, 0.0);
        self.roundtrip()?;
        wire::decode_step(&self.recv)
    }

    /// Sends `requests` in one message and reads their replies into `replies` (cleared), in
    /// order: one round trip for the lot. The first refused command is the error.
    pub fn batch(&mut self, requests: &[Request<'_>], replies: &mut Vec<Reply>) -> Result<(), SumoError> {
        // Nothing to send, nothing to wait for: SUMO answers no empty message.
        if requests.is_empty() {
            replies.clear();
            return Ok(());
        }
        wire::begin(&mut self.send);
        for req in requests {
            wire::encode(&mut self.send, req);
        }
        self.roundtrip()?;
        wire::decode_replies(&self.recv, requests, replies)
    }

    fn one(&mut self, req: Request<'_>) -> Result<Reply, SumoError> {
        let mut replies = std::mem::take(&mut self.scratch);
        let result = self.batch(std::slice::from_ref(&req), &mut replies);
        let reply = replies.pop();
        self.scratch = replies;
        result?;
        reply.ok_or_else(|| SumoError::protocol("reply count", "no reply to a request"))
    }

    fn number(&mut self, req: Request<'_>) -> Result<f64, SumoError> {
        let reply = self.one(req)?;
        reply.number().ok_or_else(|| unexpected(&req, &reply))
    }

    fn text(&mut self, req: Request<'_>) -> Result<String, SumoError> {
        match self.one(req)? {
            Reply::Text(t) => Ok(t),
            other => Err(unexpected(&req, &other)),
        }
    }

    /// The simulation time in seconds.
    pub fn time_s(&mut self) -> Result<f64, SumoError> {
        self.number(Request::Time)
    }

    /// The ids of the vehicles in the network.
    pub fn vehicle_ids(&mut self) -> Result<Vec<String>, SumoError> {
        match self.one(Request::VehicleIds)? {
            Reply::Texts(ids) => Ok(ids),
            other => Err(unexpected(&Request::VehicleIds, &other)),
        }
    }

    /// Defines route `id` along `edges` (normal edges, in order).
    pub fn add_route(&mut self, id: &str, edges: &[String]) -> Result<(), SumoError> {
        self.one(Request::AddRoute { id, edges }).map(|_| ())
    }

    /// Adds vehicle `id` on route `route_id` with type `type_id` (TraCI `add`, SUMO's Python
    /// `vehicle.add`): `depart` is `now` or seconds (a vehicle added `now` enters the network in
    /// the next step), `depart_lane` an index or `first`/`best`/…, `depart_pos` the **front
    /// bumper**'s lane position in metres or `base` (rear at the lane start: front at the length
    /// plus 0.1 m), `depart_speed` m/s or `max`/…; it arrives at the end of its route. For the
    /// remaining fields use [`Request::AddVehicle`].
    #[allow(clippy::too_many_arguments)] // TraCI's parameter list, in its order
    pub fn add_vehicle(
        &mut self,
        id: &str,
        route_id: &str,
        type_id: &str,
        depart: &str,
        depart_lane: &str,
        depart_pos: &str,
        depart_speed: &str,
    ) -> Result<(), SumoError> {
        let vehicle = NewVehicle {
            id,
            route: route_id,
            vehicle_type: type_id,
            depart,
            depart_lane,
            depart_pos,
            depart_speed,
            arrival_pos: "max",
        };
        self.one(Request::AddVehicle(vehicle)).map(|_| ())
    }

    /// Teleports vehicle `id` so its **front bumper centre** is at `(x, y)` with TraCI heading
    /// `angle_deg` after the next step; `edge_id`/`lane` are hints (`""`/`-1`: none) and
    /// `keep_route` SUMO's bit set (1: onto the vehicle's route, snapped to the lane centre; 0:
    /// onto any lane; 2: anywhere, exactly). See [`MoveToXy`].
    #[allow(clippy::too_many_arguments)] // TraCI's parameter list, in its order
    pub fn move_to_xy(
        &mut self,
        id: &str,
        edge_id: &str,
        lane: i32,
        x: f64,
        y: f64,
        angle_deg: f64,
        keep_route: u8,
    ) -> Result<(), SumoError> {
        let m = MoveToXy { vehicle: id, edge: edge_id, lane, x, y, angle_deg, keep_route };
        self.one(Request::MoveToXy(m)).map(|_| ())
    }

    /// Caps a vehicle's speed at `mps` (the vehicle gets a type of its own).
    pub fn set_max_speed(&mut self, vehicle: &str, mps: f64) -> Result<(), SumoError> {
        self.one(Request::SetMaxSpeed { vehicle, mps }).map(|_| ())
    }

    /// Sets SUMO's speed mode bit set of a vehicle.
    pub fn set_speed_mode(&mut self, vehicle: &str, mode: i32) -> Result<(), SumoError> {
        self.one(Request::SetSpeedMode { vehicle, mode }).map(|_| ())
    }

    /// Sets SUMO's lane change mode bit set of a vehicle.
    pub fn set_lane_change_mode(&mut self, vehicle: &str, mode: i32) -> Result<(), SumoError> {
        self.one(Request::SetLaneChangeMode { vehicle, mode }).map(|_| ())
    }

    /// The **front bumper centre** of a vehicle, `[x, y]` in metres.
    pub fn position(&mut self, vehicle: &str) -> Result<[f64; 2], SumoError> {
        let req = Request::Vehicle { vehicle, var: VehicleVar::Position };
        let reply = self.one(req)?;
        reply.position().ok_or_else(|| unexpected(&req, &reply))
    }

    /// A vehicle's **front bumper centre** `[x, y]`, TraCI angle in degrees and speed in m/s, in
    /// one round trip.
    pub fn vehicle_pose(&mut self, vehicle: &str) -> Result<([f64; 2], f64, f64), SumoError> {
        let requests =
            [VehicleVar::Position, VehicleVar::Angle, VehicleVar::Speed].map(|var| Request::Vehicle { vehicle, var });
        let mut replies = std::mem::take(&mut self.scratch);
        let result = self.batch(&requests, &mut replies);
        let pose = match (result, replies.as_slice()) {
            (Ok(()), [Reply::Position(p), Reply::Number(angle), Reply::Number(speed)]) => Ok((*p, *angle, *speed)),
            (Ok(()), other) => Err(SumoError::protocol("reply", format!("{other:?} to a pose of '{vehicle}'"))),
            (Err(e), _) => Err(e),
        };
        self.scratch = replies;
        pose
    }

    /// A vehicle's heading in TraCI degrees (0 = north, clockwise).
    pub fn angle_deg(&mut self, vehicle: &str) -> Result<f64, SumoError> {
        self.number(Request::Vehicle { vehicle, var: VehicleVar::Angle })
    }

    /// A vehicle's speed in m/s.
    pub fn speed(&mut self, vehicle: &str) -> Result<f64, SumoError> {
        self.number(Request::Vehicle { vehicle, var: VehicleVar::Speed })
    }

    /// A vehicle's acceleration over the last step in m/s².
    pub fn acceleration(&mut self, vehicle: &str) -> Result<f64, SumoError> {
        self.number(Request::Vehicle { vehicle, var: VehicleVar::Acceleration })
    }

    /// The lane the front bumper of a vehicle is on.
    pub fn lane_id(&mut self, vehicle: &str) -> Result<String, SumoError> {
        self.text(Request::Vehicle { vehicle, var: VehicleVar::LaneId })
    }

    /// The edge the front bumper of a vehicle is on (internal edges start with `:`).
    pub fn road_id(&mut self, vehicle: &str) -> Result<String, SumoError> {
        self.text(Request::Vehicle { vehicle, var: VehicleVar::RoadId })
    }

    /// The distance of a vehicle's front bumper from the start of its lane, metres.
    pub fn lane_position(&mut self, vehicle: &str) -> Result<f64, SumoError> {
        self.number(Request::Vehicle { vehicle, var: VehicleVar::LanePosition })
    }

    /// Ends the simulation (TraCI *close*) and waits for SUMO to exit, killing it after 2 s.
    pub fn close(mut self) -> Result<(), SumoError> {
        wire::begin(&mut self.send);
        wire::encode_close(&mut self.send);
        let closed = self.roundtrip().and_then(|()| wire::decode_status(&self.recv, wire::CMD_CLOSE, "close()"));
        let deadline = Instant::now() + EXIT_GRACE;
        while matches!(self.child.try_wait(), Ok(None)) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(5));
        }
        closed
    }

    /// Sends the message in `send` and reads the reply's content into `recv`.
    fn roundtrip(&mut self) -> Result<(), SumoError> {
        wire::finish(&mut self.send)?;
        if let Err(source) = self.stream.write_all(&self.send) {
            return Err(self.lost("sending a TraCI message to SUMO", source));
        }
        let mut header = [0u8; 4];
        if let Err(source) = self.stream.read_exact(&mut header) {
            return Err(self.lost("reading SUMO's TraCI reply", source));
        }
        let len = wire::body_len(header)?;
        self.recv.clear();
        self.recv.resize(len, 0);
        if let Err(source) = self.stream.read_exact(&mut self.recv) {
            return Err(self.lost("reading SUMO's TraCI reply", source));
        }
        Ok(())
    }

    /// An IO error on the connection, with SUMO's state and last output.
    fn lost(&mut self, doing: &str, source: std::io::Error) -> SumoError {
        use std::io::ErrorKind::{BrokenPipe, ConnectionAborted, ConnectionReset, UnexpectedEof};
        if matches!(source.kind(), BrokenPipe | ConnectionAborted | ConnectionReset | UnexpectedEof) {
            // SUMO closed the connection: it is most likely quitting; let it finish.
            let deadline = Instant::now() + EXIT_GRACE;
            while matches!(self.child.try_wait(), Ok(None)) && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        let state = match self.child.try_wait() {
            Ok(Some(status)) => format!("SUMO exited ({status})"),
            Ok(None) if matches!(source.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                format!("SUMO did not answer within {} s", READ_TIMEOUT.as_secs())
            }
            _ => "SUMO is running".to_owned(),
        };
        let output = self.output.final_tail_if_exited(&mut self.child);
        SumoError::Io { context: format!("{doing} ({state}; its output ends with:\n{output}\n)"), source }
    }
}

impl Drop for Sumo {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

fn unexpected(req: &Request<'_>, reply: &Reply) -> SumoError {
    SumoError::protocol("reply", format!("{reply:?} to {}", req.describe()))
}

/// A loopback port nothing listens on now (bound, read, released).
fn free_port() -> Result<u16, SumoError> {
    let listener =
        TcpListener::bind((Ipv4Addr::LOCALHOST, 0)).map_err(SumoError::io("finding a free loopback port for TraCI"))?;
    let port = listener.local_addr().map_err(SumoError::io("reading the free port"))?.port();
    Ok(port)
}

/// Connects to SUMO on `port`, retrying until [`CONNECT_TIMEOUT`]; fails early when SUMO exits.
fn connect(child: &mut Child, port: u16, output: &mut Output) -> Result<TcpStream, SumoError> {
    let addr = SocketAddr::from((Ipv4Addr::LOCALHOST, port));
    let deadline = Instant::now() + CONNECT_TIMEOUT;
    loop {
        if let Ok(Some(status)) = child.try_wait() {
            let reason = format!("SUMO exited ({status}) before accepting the connection");
            return Err(SumoError::Connect { port, reason, output_tail: output.final_tail() });
        }
        match TcpStream::connect_timeout(&addr, Duration::from_millis(500)) {
            Ok(stream) => {
                let setup = stream
                    .set_nodelay(true)
                    .and_then(|()| stream.set_read_timeout(Some(READ_TIMEOUT)))
                    .and_then(|()| stream.set_write_timeout(Some(READ_TIMEOUT)));
                return setup.map(|()| stream).map_err(SumoError::io("configuring the TraCI socket"));
            }
            Err(e) if Instant::now() >= deadline => {
                let reason = format!("nothing accepted within {} s: {e}", CONNECT_TIMEOUT.as_secs());
                return Err(SumoError::Connect { port, reason, output_tail: output.tail() });
            }
            Err(_) => std::thread::sleep(Duration::from_millis(20)),
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn opts() -> StartOptions {
        StartOptions {
            net: PathBuf::from("a.net.xml"),
            additional: vec![PathBuf::from("t.add.xml"), PathBuf::from("u.add.xml")],
            step_length_s: 0.1,
            seed: 7,
            extra_args: vec!["--lateral-resolution".to_owned(), "0.8".to_owned()],
        }
    }

    #[test]
    fn options_become_sumos_command_line() {
        let args = opts().args().unwrap();
        let line = args.join(" ");
        assert!(
            line.starts_with(
                "--net-file a.net.xml --additional-files t.add.xml,u.add.xml --step-length 0.1 --seed 7 --begin 0"
            ),
            "{line}"
        );
        for part in [
            "--no-step-log true",
            "--no-warnings false",
            "--collision.action warn",
            "--collision.check-junctions true",
            "--time-to-teleport -1",
            "--step-method.ballistic true",
        ] {
            assert!(line.contains(part), "{part} in {line}");
        }
        assert!(line.ends_with("--lateral-resolution 0.8"), "{line}");
        assert!(!line.contains("remote-port"));
        let bare = StartOptions { additional: Vec::new(), ..opts() };
        assert!(!bare.args().unwrap().join(" ").contains("--additional-files"));
    }

    #[test]
    fn options_sumo_cannot_take_are_refused() {
        for bad in [0.0, -0.1, f64::NAN, f64::INFINITY] {
            let o = StartOptions { step_length_s: bad, ..opts() };
            assert!(matches!(o.args(), Err(SumoError::InvalidArgument { what: "step_length_s", .. })));
        }
        let big = StartOptions { seed: 1 << 31, ..opts() };
        assert!(matches!(big.args(), Err(SumoError::InvalidArgument { what: "seed", .. })));
        let comma = StartOptions { net: PathBuf::from("a,b.net.xml"), ..opts() };
        assert!(matches!(comma.args(), Err(SumoError::InvalidArgument { what: "net", .. })));
    }
}
