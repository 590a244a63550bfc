//! Importers for the public track formats users own: INTERACTION/highD-style CSV ([`csv`]) and
//! CommonRoad XML ([`commonroad`]). Both parse text into an [`crate::tracks::Episode`]; reading
//! the file is the caller's (or the `*_file` helpers').

pub mod commonroad;
pub mod csv;
