//! How large a file a user or a peer hands us may be, checked **before** it is parsed: the size
//! on disk first, then the bytes actually read (a pipe or a growing file says nothing true about
//! its size). A refused file therefore costs at most its bound in memory, and every bound is at
//! most [`LARGEST_BOUND_BYTES`]. A parser takes a small multiple of its text (a TOML card about
//! 35×, a JSON prior about 17×), so the bounds sit well above any real file of the kind and well
//! below what would exhaust a small computer.

use std::io::Read;
use std::path::Path;

/// The largest bound of any kind, bytes (256 MiB).
pub const LARGEST_BOUND_BYTES: u64 = 256 << 20;

/// The bound on one kind of file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SizeBound {
    /// What the file is, for the error ("a scenario card or other TOML file").
    pub what: &'static str,
    /// The most bytes it may hold.
    pub max_bytes: u64,
}

/// TOML configuration: scenario cards, vehicles, settings, drivers (a card at its element bounds,
/// 1,000 segments and 10,000 profile points, is under 0.5 MiB).
pub const CONFIG: SizeBound = SizeBound { what: "a TOML file (card, vehicle, settings)", max_bytes: 4 << 20 };
/// Scenario semantics (a few kB).
pub const SEMANTICS: SizeBound = SizeBound { what: "scenario semantics", max_bytes: 1 << 20 };
/// Trajectory priors (512 samples per agent).
pub const PRIOR: SizeBound = SizeBound { what: "a trajectory prior", max_bytes: 16 << 20 };
/// Grounded scenarios, and a document that may be either it or a prior.
pub const GROUNDED: SizeBound = SizeBound { what: "a grounded scenario or prior", max_bytes: 64 << 20 };
/// The human reference of motion (the shipped one is 18 kB).
pub const HUMAN_REFERENCE: SizeBound = SizeBound { what: "a human reference", max_bytes: 16 << 20 };
/// Run files (`sim --json`: about 15 kB per simulated second with the full trace).
pub const RUN: SizeBound = SizeBound { what: "a run file", max_bytes: LARGEST_BOUND_BYTES };
/// A campaign's memory of one VUT (cases × runs, a few kB per case).
pub const CAMPAIGN_MEMORY: SizeBound = SizeBound { what: "a campaign memory", max_bytes: 64 << 20 };
/// Recorded driving to import (CommonRoad XML, CSV tracks) and training corpora (JSONL).
pub const DRIVING_DATA: SizeBound = SizeBound { what: "recorded driving or a corpus", max_bytes: LARGEST_BOUND_BYTES };
/// Denoiser weights (the shipped ones are 0.9 MB).
pub const WEIGHTS: SizeBound = SizeBound { what: "a weights file", max_bytes: 64 << 20 };
/// A VLM prompt, cassette exchange or recorded answer.
pub const VLM_FILE: SizeBound = SizeBound { what: "a VLM prompt or cassette file", max_bytes: 16 << 20 };
/// OpenDRIVE maps.
pub const MAP: SizeBound = SizeBound { what: "an OpenDRIVE map", max_bytes: LARGEST_BOUND_BYTES };
/// A session log of `video2track serve --log` (JSON lines: 10 Hz telemetry per BV, a few hours).
pub const SESSION_LOG: SizeBound = SizeBound { what: "a session log", max_bytes: LARGEST_BOUND_BYTES };
/// MCAP recordings.
pub const RECORDING: SizeBound = SizeBound { what: "an MCAP recording", max_bytes: LARGEST_BOUND_BYTES };

/// A file over its bound.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{size} is more than the {max_bytes} bytes allowed for {what} (see \"Bounds on input\" in docs/GUIDE.md)")]
pub struct TooLarge {
    /// What the file was read as.
    pub what: &'static str,
    /// The bound, bytes.
    pub max_bytes: u64,
    /// "N bytes", or "more than N bytes" when reading stopped at the bound.
    pub size: String,
}

/// Reads at most `bound` bytes of `path`. A file over its bound is the I/O error of kind
/// [`std::io::ErrorKind::FileTooLarge`] holding a [`TooLarge`], so every reader keeps its one
/// error path for "cannot read".
pub fn read_bytes_within(path: &Path, bound: SizeBound) -> std::io::Result<Vec<u8>> {
    let file = std::fs::File::open(path)?;
    let too_large = |size: String| {
        std::io::Error::new(
            std::io::ErrorKind::FileTooLarge,
            TooLarge { what: bound.what, max_bytes: bound.max_bytes, size },
        )
    };
    let on_disk = file.metadata()?.len();
    if on_disk > bound.max_bytes {
        return Err(too_large(format!("{on_disk} bytes")));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(on_disk).unwrap_or(0));
    file.take(bound.max_bytes.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > bound.max_bytes {
        return Err(too_large(format!("more than {} bytes", bound.max_bytes)));
    }
    Ok(bytes)
}

/// Reads at most `bound` bytes of `path` as UTF-8 text (see [`read_bytes_within`]).
pub fn read_text_within(path: &Path, bound: SizeBound) -> std::io::Result<String> {
    String::from_utf8(read_bytes_within(path, bound)?)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e.utf8_error()))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn too_large(e: &std::io::Error) -> &TooLarge {
        e.get_ref().and_then(|inner| inner.downcast_ref::<TooLarge>()).unwrap()
    }

    #[test]
    fn every_bound_is_at_most_the_largest() {
        for b in [
            CONFIG,
            SEMANTICS,
            PRIOR,
            GROUNDED,
            HUMAN_REFERENCE,
            CAMPAIGN_MEMORY,
            DRIVING_DATA,
            WEIGHTS,
            VLM_FILE,
            RUN,
            MAP,
            RECORDING,
        ] {
            assert!(b.max_bytes <= LARGEST_BOUND_BYTES, "{b:?}");
        }
    }

    #[test]
    fn a_file_over_its_bound_is_refused_before_it_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.toml");
        // Sparse: a terabyte on paper, nothing on disk; reading it would never end.
        std::fs::File::create(&path).unwrap().set_len(1 << 40).unwrap();
        let e = read_text_within(&path, CONFIG).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::FileTooLarge);
        assert_eq!(too_large(&e).size, format!("{} bytes", 1u64 << 40));
        assert!(e.to_string().contains("4194304 bytes allowed for a TOML file"), "{e}");
        let small = dir.path().join("small.toml");
        std::fs::write(&small, "a = 1\n").unwrap();
        assert_eq!(read_text_within(&small, CONFIG).unwrap(), "a = 1\n");
        let exact = dir.path().join("exact");
        std::fs::write(&exact, vec![b'x'; 1 << 20]).unwrap();
        assert!(read_text_within(&exact, SEMANTICS).is_ok(), "the bound itself is allowed");
        std::fs::write(&exact, vec![b'x'; (1 << 20) + 1]).unwrap();
        assert!(read_text_within(&exact, SEMANTICS).is_err());
    }

    #[cfg(unix)]
    #[test]
    fn a_pipe_is_read_only_up_to_its_bound() {
        // /dev/zero says its size is 0 and never ends: reading stops one byte past the bound.
        let e = read_bytes_within(Path::new("/dev/zero"), SEMANTICS).unwrap_err();
        assert_eq!(too_large(&e).size, "more than 1048576 bytes");
    }
}
