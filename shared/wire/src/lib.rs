//! Video2Track wire types (IPC payloads).
