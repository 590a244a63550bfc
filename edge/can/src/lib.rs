//! Video2Track drive-by-wire CAN.
