//! What can go wrong reading a map.

/// A map that cannot be used, or a part of one that cannot.
#[derive(Debug, thiserror::Error)]
pub enum MapError {
    /// The file cannot be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not well-formed XML, or not OpenDRIVE.
    #[error("not OpenDRIVE XML: {0}")]
    Xml(String),
    /// A required attribute is missing.
    #[error("{context}: <{element}> lacks the attribute {attribute} (line {line})")]
    Missing {
        /// The road, lane or junction.
        context: String,
        /// The element.
        element: String,
        /// The attribute.
        attribute: String,
        /// Line in the file.
        line: u32,
    },
    /// A value is out of its domain.
    #[error("{context}: {message}")]
    Invalid {
        /// The road, lane or junction.
        context: String,
        /// What is wrong.
        message: String,
    },
    /// A plan-view geometry this parser does not know.
    #[error("{context}: unknown plan-view geometry <{kind}>")]
    UnknownGeometry {
        /// The road and s.
        context: String,
        /// The element name.
        kind: String,
    },
    /// A file's text is not a usable map (what [`Map::load`](crate::Map::load) says of a file that
    /// reads but does not parse): the file, then why.
    #[error("{path}: {error}")]
    File {
        /// The file.
        path: String,
        /// Why (not a cause of its own: the message shows it).
        error: Box<MapError>,
    },
    /// Annotations that do not fit the map.
    #[error("annotations {path}: {message}")]
    Annotations {
        /// The file.
        path: String,
        /// What is wrong.
        message: String,
    },
}

/// Something in a map that was left out or looks wrong, while the rest is usable.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct MapWarning {
    /// The road, lane, junction or connection.
    pub context: String,
    /// What happened.
    pub message: String,
}

impl MapWarning {
    /// A warning about `context`.
    pub fn new(context: impl Into<String>, message: impl Into<String>) -> Self {
        Self { context: context.into(), message: message.into() }
    }
}

impl std::fmt::Display for MapWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.context, self.message)
    }
}
