//! The one error type of the crate: every variant says what failed and, where it can, how to fix it.

use std::path::PathBuf;

/// How to install SUMO, quoted by [`SumoError::MissingBinaries`] and by the tests that need it.
pub const INSTALL_HINT: &str = "run `scripts/install-sumo` (it creates target/sumo-venv with \
    `pip install eclipse-sumo==1.28.0`), or `pip install eclipse-sumo==1.28.0` yourself and set \
    V2T_SUMO_BIN to the directory that holds `sumo` and `netconvert`";

/// What went wrong talking to SUMO, running its tools or reading its files.
#[derive(Debug, thiserror::Error)]
pub enum SumoError {
    /// `sumo` or `netconvert` was found nowhere.
    #[error("SUMO's `sumo` and `netconvert` were not found (looked in: {searched}): {INSTALL_HINT}")]
    MissingBinaries {
        /// The places looked in, in order.
        searched: String,
    },
    /// A SUMO program could not be started at all.
    #[error("could not start `{command}`: {source}")]
    Spawn {
        /// The command line.
        command: String,
        /// Why the operating system refused.
        source: std::io::Error,
    },
    /// A SUMO tool (netconvert, `sumo --version`) ran and failed.
    #[error("`{command}` failed ({status}); its output ends with:\n{output_tail}")]
    ToolFailed {
        /// The command line.
        command: String,
        /// Its exit status.
        status: String,
        /// The last lines it wrote (warnings included).
        output_tail: String,
    },
    /// SUMO did not accept the TraCI connection.
    #[error("could not connect to SUMO's TraCI port {port}: {reason}; SUMO's output ends with:\n{output_tail}")]
    Connect {
        /// The loopback port SUMO was told to listen on.
        port: u16,
        /// What happened (SUMO exited, or the time ran out).
        reason: String,
        /// The last lines SUMO wrote.
        output_tail: String,
    },
    /// A TraCI message broke the protocol: a field out of its bounds, a wrong id or type, a
    /// truncated message.
    #[error("malformed TraCI message: {field}: {problem}")]
    Protocol {
        /// The field that was wrong.
        field: &'static str,
        /// What was wrong with it, with the bound it broke.
        problem: String,
    },
    /// SUMO speaks an older TraCI than this client.
    #[error(
        "SUMO's TraCI API version is {found} ({identifier}); this client needs {required} or newer: {INSTALL_HINT}"
    )]
    ApiVersion {
        /// The version SUMO reported.
        found: i32,
        /// SUMO's identifier string, e.g. `SUMO v1_28_0`.
        identifier: String,
        /// The oldest version this client speaks.
        required: i32,
    },
    /// SUMO answered a command with an error status.
    #[error("SUMO refused {command}: {message}")]
    Command {
        /// The command, with the object it addressed.
        command: String,
        /// SUMO's description of the error.
        message: String,
    },
    /// Reading or writing a file or the TraCI socket failed.
    #[error("{context}: {source}")]
    Io {
        /// What was being done.
        context: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A SUMO network file could not be read.
    #[error("{}: <{element}> attribute `{attribute}`: {problem}", file.display())]
    NetParse {
        /// The network file.
        file: PathBuf,
        /// The element (`edge`, `lane`, `connection`, …; `net` for the document itself).
        element: String,
        /// The attribute at fault (empty for XML syntax errors).
        attribute: String,
        /// What was wrong.
        problem: String,
    },
    /// A path sample lies farther than the bound from every lane that runs its way.
    #[error(
        "path sample {index} at ({x:.2}, {y:.2}) has no lane within {max_off_m} m running within \
         60° of its heading; the nearest lane of any heading is {nearest_lane} at {distance_m:.2} m"
    )]
    RouteMatch {
        /// The sample's index in the path.
        index: usize,
        /// The sample's x in metres.
        x: f64,
        /// The sample's y in metres.
        y: f64,
        /// The nearest lane of any heading (`none` in an empty network).
        nearest_lane: String,
        /// Its distance in metres.
        distance_m: f64,
        /// The bound the path was matched with.
        max_off_m: f64,
    },
    /// The lanes matched to a path do not make one drivable route.
    #[error("path sample {index} at ({x:.2}, {y:.2}): {problem}")]
    RouteBroken {
        /// The sample's index in the path.
        index: usize,
        /// The sample's x in metres.
        x: f64,
        /// The sample's y in metres.
        y: f64,
        /// What breaks the route, naming the lanes.
        problem: String,
    },
    /// An argument of the caller is outside what SUMO or this crate accepts.
    #[error("invalid {what}: {problem}")]
    InvalidArgument {
        /// The argument.
        what: &'static str,
        /// What is wrong with it and what is accepted.
        problem: String,
    },
}

impl SumoError {
    /// A [`SumoError::Protocol`] for `field`.
    pub(crate) fn protocol(field: &'static str, problem: impl Into<String>) -> Self {
        Self::Protocol { field, problem: problem.into() }
    }

    /// A closure that wraps an IO error with `context`, for `map_err`.
    pub(crate) fn io(context: impl Into<String>) -> impl FnOnce(std::io::Error) -> Self {
        let context = context.into();
        move |source| Self::Io { context, source }
    }
}
