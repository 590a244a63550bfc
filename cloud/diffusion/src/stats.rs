//! Statistics for realism checks: histograms and the Wasserstein-1 distance between empirical
//! one-dimensional distributions of acceleration, jerk and yaw rate.
