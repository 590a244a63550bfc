//! Video2Track path tracking.
