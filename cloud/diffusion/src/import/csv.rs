//! INTERACTION-dataset-style CSV tracks, header-driven.
//!
//! Columns are found by name (case-insensitive, in any order, unknown ones ignored):
//!
//! | field | INTERACTION | highD and other variants |
//! |---|---|---|
//! | track id (required) | `track_id` | `id`, `trackId` |
//! | frame (required) | `frame_id` | `frame` |
//! | time (required unless a frame rate is given) | `timestamp_ms` | — |
//! | position (required) | `x`, `y` | |
//! | velocity | `vx`, `vy` | `xVelocity`, `yVelocity` |
//! | heading | `psi_rad` | `heading`, `yaw` |
//! | footprint | `length`, `width` | highD: `width` (along x), `height` |
//! | kind | `agent_type` | `class`, `type` |
//!
//! A highD `tracks.csv` (recognised by `xVelocity` with `height`) gives the top-left corner of
//! the bounding box in image axes (y down): positions are moved to the box centre and y and `vy`
//! are negated so that the frame is right-handed like every other in Video2Track. highD has no
//! timestamps: pass [`CsvOptions::frame_rate_hz`] (25 Hz); its `tracksMeta.csv` (class, box) is
//! applied with [`apply_high_d_meta`].
//!
//! The parser is a small hand-written one (quoted fields with `""`, line breaks inside quotes,
//! CRLF, a BOM) rather than the `csv` crate: track files are plain and this keeps line numbers
//! exact for errors.
//!
//! Every error names the line and, where it is about a value, the column. Non-finite values and a
//! (track, frame) pair given twice are errors; missing frames inside a track are reported as
//! [`TrackGap`]s beside the episode.

use std::collections::{BTreeMap, HashMap};

use v2t_model::metrics::Dimensions;

use crate::tracks::{AgentKind, Episode, Track, TrackSample};

/// What can go wrong reading a CSV track file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CsvError {
    /// Nothing but blank lines.
    #[error("the file has no header")]
    Empty,
    /// A quoted field runs to the end of the file.
    #[error("line {line}: quoted field is not closed")]
    UnterminatedQuote {
        /// Line where the field starts (1-based).
        line: usize,
    },
    /// A required column is absent.
    #[error("header: no column `{column}` (accepted names: {accepted})")]
    MissingColumn {
        /// The canonical name.
        column: &'static str,
        /// Names that would do.
        accepted: String,
    },
    /// Two header columns map to the same field.
    #[error("header: columns `{first}` and `{second}` both give `{column}`")]
    DuplicateColumn {
        /// The canonical name.
        column: &'static str,
        /// The first header name.
        first: String,
        /// The second.
        second: String,
    },
    /// A record with a different number of fields than the header.
    #[error("line {line}: {found} fields, the header has {expected}")]
    FieldCount {
        /// Line (1-based).
        line: usize,
        /// Header fields.
        expected: usize,
        /// Record fields.
        found: usize,
    },
    /// A field that is not a number (a frame: not a whole number).
    #[error("line {line}, column `{column}`: `{value}` is not a number of the kind expected")]
    Number {
        /// Line (1-based).
        line: usize,
        /// Header name of the column.
        column: String,
        /// The text.
        value: String,
    },
    /// NaN or infinity.
    #[error("line {line}, column `{column}`: `{value}` is not finite")]
    NonFinite {
        /// Line (1-based).
        line: usize,
        /// Header name of the column.
        column: String,
        /// The text.
        value: String,
    },
    /// A (track, frame) pair given twice.
    #[error("line {line}: track `{track}` frame {frame} was already given on line {first_line}")]
    DuplicateFrame {
        /// Line of the repetition.
        line: usize,
        /// Line of the first occurrence.
        first_line: usize,
        /// Track id.
        track: String,
        /// Frame number.
        frame: i64,
    },
    /// Time does not increase with the frame number inside a track.
    #[error("line {line}: track `{track}` frame {frame} is not later than the frame before it")]
    TimeOrder {
        /// Line (1-based).
        line: usize,
        /// Track id.
        track: String,
        /// Frame number.
        frame: i64,
    },
    /// No timestamp column and no frame rate.
    #[error("header: no `timestamp_ms` column; give a frame rate to time frames")]
    NoTime,
    /// The frame rate given is not a positive finite number.
    #[error("frame rate {0} Hz is not positive and finite")]
    FrameRate(f64),
    /// The file could not be read.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// What the OS said.
        message: String,
    },
}

/// How to read a CSV.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CsvOptions {
    /// Frame rate used to time frames when there is no `timestamp_ms` column, Hz.
    pub frame_rate_hz: Option<f64>,
}

/// Frames missing inside a track.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TrackGap {
    /// Track id.
    pub track: String,
    /// Last frame before the hole.
    pub after_frame: i64,
    /// Number of frames missing.
    pub missing_frames: i64,
}

/// A parsed CSV: the episode and the holes found in its tracks.
#[derive(Debug, Clone, PartialEq)]
pub struct CsvImport {
    /// All tracks of the file.
    pub episode: Episode,
    /// Missing frames, per track in frame order.
    pub gaps: Vec<TrackGap>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Field {
    TrackId,
    Frame,
    TimestampMs,
    X,
    Y,
    Vx,
    Vy,
    Psi,
    Length,
    Width,
    Height,
    AgentType,
}

const FIELDS: [(Field, &str, &[&str]); 12] = [
    (Field::TrackId, "track_id", &["track_id", "id", "trackid", "object_id"]),
    (Field::Frame, "frame_id", &["frame_id", "frame"]),
    (Field::TimestampMs, "timestamp_ms", &["timestamp_ms"]),
    (Field::X, "x", &["x"]),
    (Field::Y, "y", &["y"]),
    (Field::Vx, "vx", &["vx", "xvelocity", "x_velocity"]),
    (Field::Vy, "vy", &["vy", "yvelocity", "y_velocity"]),
    (Field::Psi, "psi_rad", &["psi_rad", "heading", "yaw"]),
    (Field::Length, "length", &["length"]),
    (Field::Width, "width", &["width"]),
    (Field::Height, "height", &["height"]),
    (Field::AgentType, "agent_type", &["agent_type", "class", "type"]),
];

/// Column index of each field found in the header.
#[derive(Debug, Default)]
struct Columns {
    found: HashMap<usize, usize>,
    names: Vec<String>,
    high_d: bool,
}

impl Columns {
    fn from_header(names: Vec<String>) -> Result<Self, CsvError> {
        let mut found: HashMap<usize, usize> = HashMap::new();
        for (col, name) in names.iter().enumerate() {
            let key = name.trim().to_ascii_lowercase();
            let Some(f) = FIELDS.iter().position(|(_, _, aliases)| aliases.contains(&key.as_str())) else { continue };
            if let Some(&first) = found.get(&f) {
                return Err(CsvError::DuplicateColumn {
                    column: FIELDS.get(f).map_or("?", |x| x.1),
                    first: names.get(first).cloned().unwrap_or_default(),
                    second: name.clone(),
                });
            }
            found.insert(f, col);
        }
        let mut me = Self { found, names, high_d: false };
        me.high_d = me.index(Field::Height).is_some() && me.header_has("xvelocity");
        for required in [Field::TrackId, Field::Frame, Field::X, Field::Y] {
            if me.index(required).is_none() {
                let (_, column, aliases) = FIELDS.iter().find(|x| x.0 == required).copied().unwrap_or(FIELDS[0]);
                return Err(CsvError::MissingColumn { column, accepted: aliases.join(", ") });
            }
        }
        Ok(me)
    }

    fn header_has(&self, lower: &str) -> bool {
        self.names.iter().any(|n| n.trim().eq_ignore_ascii_case(lower))
    }

    fn index(&self, field: Field) -> Option<usize> {
        let f = FIELDS.iter().position(|x| x.0 == field)?;
        self.found.get(&f).copied()
    }

    fn text<'a>(&self, record: &'a [String], field: Field) -> Option<&'a str> {
        record.get(self.index(field)?).map(|s| s.trim()).filter(|s| !s.is_empty())
    }

    fn number(&self, record: &[String], field: Field, line: usize) -> Result<Option<f64>, CsvError> {
        let Some(text) = self.text(record, field) else { return Ok(None) };
        let column = self.index(field).and_then(|i| self.names.get(i)).cloned().unwrap_or_default();
        let v: f64 =
            text.parse().map_err(|_| CsvError::Number { line, column: column.clone(), value: text.to_owned() })?;
        if !v.is_finite() {
            return Err(CsvError::NonFinite { line, column, value: text.to_owned() });
        }
        Ok(Some(v))
    }

    fn required(&self, record: &[String], field: Field, line: usize) -> Result<f64, CsvError> {
        self.number(record, field, line)?.ok_or_else(|| CsvError::Number {
            line,
            column: self.index(field).and_then(|i| self.names.get(i)).cloned().unwrap_or_default(),
            value: String::new(),
        })
    }
}

/// Splits CSV text into records of fields, with the line each record starts on. Fields may be
/// quoted (`"a,b"`, `""` for a quote, line breaks inside); blank lines are skipped.
pub fn records(text: &str) -> Result<Vec<(usize, Vec<String>)>, CsvError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut out = Vec::new();
    let mut fields: Vec<String> = Vec::new();
    let mut field = String::new();
    let mut line = 1;
    let mut start_line = 1;
    let mut in_quotes = false;
    let mut quote_line = 1;
    let mut chars = text.chars().peekable();
    let mut touched = false;
    while let Some(c) = chars.next() {
        if in_quotes {
            match c {
                '"' if chars.peek() == Some(&'"') => {
                    chars.next();
                    field.push('"');
                }
                '"' => in_quotes = false,
                '\n' => {
                    line += 1;
                    field.push(c);
                }
                _ => field.push(c),
            }
            continue;
        }
        match c {
            '"' => {
                in_quotes = true;
                quote_line = line;
                touched = true;
            }
            ',' => {
                fields.push(std::mem::take(&mut field));
                touched = true;
            }
            '\r' if chars.peek() == Some(&'\n') => {}
            '\n' => {
                if touched || !field.trim().is_empty() {
                    fields.push(std::mem::take(&mut field));
                    out.push((start_line, std::mem::take(&mut fields)));
                }
                field.clear();
                touched = false;
                line += 1;
                start_line = line;
            }
            _ => field.push(c),
        }
    }
    if in_quotes {
        return Err(CsvError::UnterminatedQuote { line: quote_line });
    }
    if touched || !field.trim().is_empty() {
        fields.push(field);
        out.push((start_line, fields));
    }
    Ok(out)
}

/// One parsed row before grouping.
struct Row {
    line: usize,
    frame: i64,
    sample: TrackSample,
}

/// Per-track data gathered while reading.
#[derive(Default)]
struct Gathered {
    kind: AgentKind,
    dims: Option<Dimensions>,
    rows: Vec<Row>,
}

/// Parses CSV track text into an episode named `name`.
pub fn parse(text: &str, name: &str, options: &CsvOptions) -> Result<CsvImport, CsvError> {
    if let Some(hz) = options.frame_rate_hz
        && !(hz.is_finite() && hz > 0.0)
    {
        return Err(CsvError::FrameRate(hz));
    }
    let mut recs = records(text)?.into_iter();
    let (_, header) = recs.next().ok_or(CsvError::Empty)?;
    let cols = Columns::from_header(header)?;
    if cols.index(Field::TimestampMs).is_none() && options.frame_rate_hz.is_none() {
        return Err(CsvError::NoTime);
    }
    let mut tracks: BTreeMap<String, Gathered> = BTreeMap::new();
    let mut seen: HashMap<(String, i64), usize> = HashMap::new();
    for (line, rec) in recs {
        if rec.len() != cols.names.len() {
            return Err(CsvError::FieldCount { line, expected: cols.names.len(), found: rec.len() });
        }
        let id = cols.text(&rec, Field::TrackId).unwrap_or_default().to_owned();
        let frame_f = cols.required(&rec, Field::Frame, line)?;
        if frame_f.fract() != 0.0 || frame_f.abs() > 1e15 {
            return Err(CsvError::Number {
                line,
                column: cols.index(Field::Frame).and_then(|i| cols.names.get(i)).cloned().unwrap_or_default(),
                value: cols.text(&rec, Field::Frame).unwrap_or_default().to_owned(),
            });
        }
        let frame = frame_f as i64;
        if let Some(&first_line) = seen.get(&(id.clone(), frame)) {
            return Err(CsvError::DuplicateFrame { line, first_line, track: id, frame });
        }
        seen.insert((id.clone(), frame), line);
        let t_s = match (cols.number(&rec, Field::TimestampMs, line)?, options.frame_rate_hz) {
            (Some(ms), _) => ms / 1000.0,
            (None, Some(hz)) => frame as f64 / hz,
            (None, None) => return Err(CsvError::NoTime),
        };
        let mut x = cols.required(&rec, Field::X, line)?;
        let mut y = cols.required(&rec, Field::Y, line)?;
        let mut vy = cols.number(&rec, Field::Vy, line)?;
        let length = cols.number(&rec, Field::Length, line)?;
        let width = cols.number(&rec, Field::Width, line)?;
        let height = cols.number(&rec, Field::Height, line)?;
        let dims = if cols.high_d {
            // highD: `width` is the box along x, `height` across; (x, y) its top-left corner.
            let (w, h) = (width.unwrap_or(0.0), height.unwrap_or(0.0));
            x += 0.5 * w;
            y = -(y + 0.5 * h);
            vy = vy.map(|v| -v);
            Some(Dimensions { length_m: w, width_m: h })
        } else {
            length.zip(width).map(|(l, w)| Dimensions { length_m: l, width_m: w })
        };
        let sample =
            TrackSample { t_s, x_m: x, y_m: y, vx_mps: cols.number(&rec, Field::Vx, line)?, vy_mps: vy, psi_rad: None };
        let sample = TrackSample { psi_rad: cols.number(&rec, Field::Psi, line)?, ..sample };
        let g = tracks.entry(id).or_default();
        if let Some(label) = cols.text(&rec, Field::AgentType) {
            g.kind = AgentKind::from_label(label);
        }
        if dims.is_some() {
            g.dims = dims;
        }
        g.rows.push(Row { line, frame, sample });
    }
    let mut gaps = Vec::new();
    let mut out = Vec::new();
    for (id, mut g) in tracks {
        g.rows.sort_by_key(|r| r.frame);
        let mut periods = Vec::new();
        for w in g.rows.windows(2) {
            let [a, b] = w else { continue };
            let frames = b.frame - a.frame;
            if b.sample.t_s <= a.sample.t_s {
                return Err(CsvError::TimeOrder { line: b.line, track: id, frame: b.frame });
            }
            if frames > 1 {
                gaps.push(TrackGap { track: id.clone(), after_frame: a.frame, missing_frames: frames - 1 });
            }
            periods.push((b.sample.t_s - a.sample.t_s) / frames as f64);
        }
        let fallback = options.frame_rate_hz.map_or(0.1, |hz| 1.0 / hz);
        let dt_s = crate::stats::median(&mut periods).unwrap_or(fallback);
        let samples = g.rows.into_iter().map(|r| r.sample).collect();
        out.push(Track { id, dt_s, kind: g.kind, dims: g.dims, samples });
    }
    Ok(CsvImport { episode: Episode::from_tracks(name, out), gaps })
}

/// Reads and parses a CSV file; the episode is named after the file stem.
pub fn parse_file(path: &std::path::Path, options: &CsvOptions) -> Result<CsvImport, CsvError> {
    let text = v2t_files::bounds::read_text_within(path, v2t_files::bounds::DRIVING_DATA)
        .map_err(|e| CsvError::Io { path: path.display().to_string(), message: e.to_string() })?;
    let stem = path.file_stem().map_or_else(|| "csv".to_owned(), |s| s.to_string_lossy().into_owned());
    parse(&text, &stem, options)
}

/// Applies a highD `tracksMeta.csv` (columns `id`, `width`, `height`, `class`, by name) to an
/// episode read from the matching `tracks.csv`: each track gets its class as kind and the box as
/// footprint. Returns the number of tracks updated; ids absent from the episode are ignored.
pub fn apply_high_d_meta(episode: &mut Episode, meta: &str) -> Result<usize, CsvError> {
    let mut recs = records(meta)?.into_iter();
    let (_, header) = recs.next().ok_or(CsvError::Empty)?;
    let col = |name: &'static str| {
        header
            .iter()
            .position(|h| h.trim().eq_ignore_ascii_case(name))
            .ok_or(CsvError::MissingColumn { column: name, accepted: name.to_owned() })
    };
    let (id_c, w_c, h_c, class_c) = (col("id")?, col("width")?, col("height")?, col("class")?);
    let mut updated = 0;
    for (line, rec) in recs {
        if rec.len() != header.len() {
            return Err(CsvError::FieldCount { line, expected: header.len(), found: rec.len() });
        }
        let field = |c: usize| rec.get(c).map(|s| s.trim()).unwrap_or_default();
        let number = |c: usize| {
            let text = field(c);
            let column = header.get(c).cloned().unwrap_or_default();
            match text.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                Ok(_) => Err(CsvError::NonFinite { line, column, value: text.to_owned() }),
                Err(_) => Err(CsvError::Number { line, column, value: text.to_owned() }),
            }
        };
        let (length_m, width_m) = (number(w_c)?, number(h_c)?);
        if let Some(t) = episode.tracks.iter_mut().find(|t| t.id == field(id_c)) {
            t.kind = AgentKind::from_label(field(class_c));
            t.dims = Some(Dimensions { length_m, width_m });
            updated += 1;
        }
    }
    Ok(updated)
}

/// Writes an episode as INTERACTION-style CSV (`track_id,frame_id,timestamp_ms,agent_type,x,y,vx,
/// vy,psi_rad,length,width`); frame ids are `round(t / dt)` of the episode's period, empty fields
/// stand for values not recorded. Numbers are written in the shortest form that reads back exactly.
pub fn write(episode: &Episode) -> String {
    let mut out = String::from("track_id,frame_id,timestamp_ms,agent_type,x,y,vx,vy,psi_rad,length,width\n");
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v}"));
    for t in &episode.tracks {
        let kind = serde_json::to_value(t.kind).ok().and_then(|v| v.as_str().map(str::to_owned)).unwrap_or_default();
        let id =
            if t.id.contains([',', '"', '\n']) { format!("\"{}\"", t.id.replace('"', "\"\"")) } else { t.id.clone() };
        for s in &t.samples {
            let frame = (s.t_s / episode.dt_s).round() as i64;
            // Whole milliseconds as integers, like the datasets; anything else exactly.
            let ms = s.t_s * 1000.0;
            let ms = if (ms - ms.round()).abs() < 1e-6 { format!("{}", ms.round()) } else { format!("{ms}") };
            out.push_str(&format!(
                "{id},{frame},{ms},{kind},{},{},{},{},{},{},{}\n",
                s.x_m,
                s.y_m,
                opt(s.vx_mps),
                opt(s.vy_mps),
                opt(s.psi_rad),
                opt(t.dims.map(|d| d.length_m)),
                opt(t.dims.map(|d| d.width_m)),
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const INTERACTION: &str = "track_id,frame_id,timestamp_ms,agent_type,x,y,vx,vy,psi_rad,length,width\n\
        1,1,100,car,1000.5,980.25,5.0,0.0,0.0,4.5,1.8\n\
        1,2,200,car,1001.0,980.25,5.0,0.0,0.0,4.5,1.8\n\
        1,4,400,car,1002.0,980.25,5.0,0.0,0.0,4.5,1.8\n\
        2,1,100,truck,990.0,975.0,,,,12.0,2.5\n\
        2,2,200,truck,990.9,975.0,,,,12.0,2.5\n";

    #[test]
    fn interaction_file_reads_with_gaps_reported() {
        let r = parse(INTERACTION, "rec", &CsvOptions::default()).unwrap();
        assert_eq!(r.episode.tracks.len(), 2);
        let t1 = &r.episode.tracks[0];
        assert_eq!(t1.samples.len(), 3);
        assert!((t1.dt_s - 0.1).abs() < 1e-12);
        assert_eq!(t1.kind, AgentKind::Car);
        assert_eq!(t1.dims, Some(Dimensions { length_m: 4.5, width_m: 1.8 }));
        assert_eq!(t1.samples[0].vx_mps, Some(5.0));
        let t2 = &r.episode.tracks[1];
        assert_eq!(t2.kind, AgentKind::Truck);
        assert_eq!(t2.samples[0].vx_mps, None);
        assert_eq!(r.gaps, vec![TrackGap { track: "1".into(), after_frame: 2, missing_frames: 1 }]);
        assert!((r.episode.t_end_s - 0.4).abs() < 1e-12);
    }

    #[test]
    fn high_d_names_are_mapped_and_the_box_centred() {
        let text = "frame,id,x,y,width,height,xVelocity,yVelocity,xAcceleration\n\
            1,7,10.0,20.0,4.0,2.0,30.0,0.5,0.1\n2,7,11.2,20.0,4.0,2.0,30.0,0.5,0.1\n";
        assert_eq!(parse(text, "h", &CsvOptions::default()).unwrap_err(), CsvError::NoTime);
        let r = parse(text, "h", &CsvOptions { frame_rate_hz: Some(25.0) }).unwrap();
        let t = &r.episode.tracks[0];
        assert!((t.dt_s - 0.04).abs() < 1e-12);
        assert_eq!((t.samples[0].x_m, t.samples[0].y_m), (12.0, -21.0));
        assert_eq!(t.samples[0].vy_mps, Some(-0.5));
        assert_eq!(t.dims, Some(Dimensions { length_m: 4.0, width_m: 2.0 }));
    }

    #[test]
    fn high_d_meta_gives_class_and_box() {
        let text = "frame,id,x,y,width,height,xVelocity,yVelocity\n1,7,10,20,4,2,30,0\n2,7,11.2,20,4,2,30,0\n";
        let mut e = parse(text, "h", &CsvOptions { frame_rate_hz: Some(25.0) }).unwrap().episode;
        let meta = "id,width,height,initialFrame,class\n7,15.2,2.5,1,Truck\n8,4.1,1.9,9,Car\n";
        assert_eq!(apply_high_d_meta(&mut e, meta).unwrap(), 1);
        assert_eq!(e.tracks[0].kind, AgentKind::Truck);
        assert_eq!(e.tracks[0].dims, Some(Dimensions { length_m: 15.2, width_m: 2.5 }));
        let bad = "id,width,height,class\n7,x,2.5,Car\n";
        assert!(matches!(apply_high_d_meta(&mut e, bad), Err(CsvError::Number { line: 2, .. })));
        assert!(matches!(
            apply_high_d_meta(&mut e, "id,width\n"),
            Err(CsvError::MissingColumn { column: "height", .. })
        ));
    }

    #[test]
    fn errors_name_line_and_column() {
        let opts = CsvOptions::default();
        let bad_number = "track_id,frame_id,timestamp_ms,x,y\n1,1,100,0,0\n1,2,200,abc,0\n";
        assert_eq!(
            parse(bad_number, "e", &opts).unwrap_err(),
            CsvError::Number { line: 3, column: "x".into(), value: "abc".into() }
        );
        let nan = "track_id,frame_id,timestamp_ms,x,y\n1,1,100,0,NaN\n";
        let e = parse(nan, "e", &opts).unwrap_err();
        assert_eq!(e, CsvError::NonFinite { line: 2, column: "y".into(), value: "NaN".into() });
        assert!(e.to_string().contains("line 2"));
        let inf = "track_id,frame_id,timestamp_ms,x,y\n1,1,100,inf,0\n";
        assert!(matches!(parse(inf, "e", &opts), Err(CsvError::NonFinite { line: 2, .. })));
        let dup = "track_id,frame_id,timestamp_ms,x,y\n1,1,100,0,0\n2,1,100,0,0\n1,1,100,1,0\n";
        assert_eq!(
            parse(dup, "e", &opts).unwrap_err(),
            CsvError::DuplicateFrame { line: 4, first_line: 2, track: "1".into(), frame: 1 }
        );
        let short = "track_id,frame_id,timestamp_ms,x,y\n1,1,100,0\n";
        assert_eq!(parse(short, "e", &opts).unwrap_err(), CsvError::FieldCount { line: 2, expected: 5, found: 4 });
        let half_frame = "track_id,frame_id,timestamp_ms,x,y\n1,1.5,100,0,0\n";
        assert!(matches!(parse(half_frame, "e", &opts), Err(CsvError::Number { line: 2, .. })));
        let missing = "track_id,timestamp_ms,x,y\n";
        assert!(matches!(parse(missing, "e", &opts), Err(CsvError::MissingColumn { column: "frame_id", .. })));
        let twice = "track_id,id,frame_id,timestamp_ms,x,y\n";
        assert!(matches!(parse(twice, "e", &opts), Err(CsvError::DuplicateColumn { column: "track_id", .. })));
        assert_eq!(parse("\n\n", "e", &opts).unwrap_err(), CsvError::Empty);
        let backwards = "track_id,frame_id,timestamp_ms,x,y\n1,1,200,0,0\n1,2,100,0,0\n";
        assert!(matches!(parse(backwards, "e", &opts), Err(CsvError::TimeOrder { line: 3, .. })));
    }

    #[test]
    fn quoted_fields_crlf_and_bom() {
        let text = "\u{feff}track_id,frame_id,timestamp_ms,x,y,agent_type\r\n\"a,1\",1,100,0,0,\"car\"\r\n\r\n\"a,1\",2,200,1,0,car\r\n";
        let r = parse(text, "q", &CsvOptions::default()).unwrap();
        assert_eq!(r.episode.tracks[0].id, "a,1");
        assert_eq!(r.episode.tracks[0].samples.len(), 2);
        let recs = records("a,\"b\"\"c\nd\",e\nf,g,h").unwrap();
        assert_eq!(recs[0], (1, vec!["a".to_owned(), "b\"c\nd".to_owned(), "e".to_owned()]));
        assert_eq!(recs[1].0, 3);
        assert_eq!(records("a,\"b\n").unwrap_err(), CsvError::UnterminatedQuote { line: 1 });
    }

    fn sample_strategy() -> impl Strategy<Value = (f64, f64, Option<f64>, Option<f64>, Option<f64>)> {
        (
            -1e4f64..1e4,
            -1e4f64..1e4,
            prop::option::of(-40.0f64..40.0),
            prop::option::of(-40.0f64..40.0),
            prop::option::of(-3.2f64..3.2),
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn written_tracks_read_back(
            tracks in prop::collection::vec(
                (0i64..50, prop::collection::vec(sample_strategy(), 1..30), prop::option::of((2.0f64..15.0, 1.0f64..3.0)), 0usize..4),
                1..5),
        ) {
            let kinds = [AgentKind::Car, AgentKind::Truck, AgentKind::Bicycle, AgentKind::Unknown];
            let built: Vec<Track> = tracks.iter().enumerate().map(|(i, (start, samples, dims, kind))| Track {
                id: format!("{i}"),
                dt_s: 0.1,
                kind: kinds[*kind],
                dims: dims.map(|(l, w)| Dimensions { length_m: l, width_m: w }),
                samples: samples.iter().enumerate().map(|(k, (x, y, vx, vy, psi))| TrackSample {
                    t_s: (100 * (start + k as i64)) as f64 / 1000.0,
                    x_m: *x, y_m: *y, vx_mps: *vx, vy_mps: *vy, psi_rad: *psi,
                }).collect(),
            }).collect();
            let episode = Episode::from_tracks("p", built);
            let back = parse(&write(&episode), "p", &CsvOptions::default()).unwrap();
            prop_assert!(back.gaps.is_empty());
            prop_assert_eq!(back.episode.tracks.len(), episode.tracks.len());
            for (a, b) in episode.tracks.iter().zip(&back.episode.tracks) {
                prop_assert_eq!(&a.id, &b.id);
                prop_assert_eq!(a.kind, b.kind);
                prop_assert_eq!(a.dims, b.dims);
                prop_assert_eq!(a.samples.len(), b.samples.len());
                if a.samples.len() > 1 { prop_assert!((a.dt_s - b.dt_s).abs() < 1e-9); }
                for (p, q) in a.samples.iter().zip(&b.samples) {
                    prop_assert!((p.t_s - q.t_s).abs() < 1e-9);
                    prop_assert_eq!((p.x_m, p.y_m, p.vx_mps, p.vy_mps, p.psi_rad), (q.x_m, q.y_m, q.vx_mps, q.vy_mps, q.psi_rad));
                }
            }
        }
    }
}
