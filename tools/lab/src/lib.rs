//! # v2t-lab — the laboratory: simulated worlds and everything that compares or measures
//!
//! Nothing here ships to a vehicle: the onboard runtime (`v2t-edge`) never links this crate or
//! the simulator. What lives here:
//!
//! - [`world`]: how a prior becomes a simulated run — the one conversion from trajectory priors
//!   and accepted IPC priors to scenarios of the simulated proving ground (`v2t-sim`), and from
//!   scenario cards back to the prior a BV would receive;
//! - [`vut`] and [`sumo`]: the VUT a run faces — one of this project's driver models in the builtin
//!   world, or one of Eclipse SUMO's drivers in the SUMO world (SUMO drives the VUT on the network
//!   converted from the same map, our BVs are imposed on it every control period);
//! - [`reach`]: which PETs any BV can reach against a VUT (an open-loop grid, for scoring only);
//! - [`controllers`]: the onboard algorithms as BV controllers of the simulated proving ground;
//! - [`stats`]: the statistics of repeated runs every experiment reports;
//! - [`sim`]: one run with reference-following BVs (`video2track sim`);
//! - [`steer`], [`methods`] and [`tradeoff`]: the experiments (`video2track experiment …`), the
//!   regulator alone on the scenario cards, the paper's four methods on its scenarios, and the
//!   sweep of the regulator's realism weight;
//! - [`latency`]: the regulator onboard against the same regulator in the cloud across a simulated
//!   network (`video2track experiment latency`);
//! - [`campaign`]: one test repeated as a proving ground repeats it, the regulator learning the
//!   VUT's reaction from run to run (`video2track experiment campaign`, `sim --campaign`);
//! - [`demo`]: the whole pipeline end to end through the onboard processes (`video2track demo`);
//! - [`ecu`]: the simulated drive-by-wire ECU behind the real CAN frames (binary `v2t-sim-ecu`);
//! - [`bench_latency`] and [`bench_game`]: the benches (binary `v2t-bench`).
//!
//! Every figure that comes out of here comes from a simulated world, with VUT driver models this
//! project wrote or, in the SUMO world, SUMO's; outputs say which.
//!
//! ```
//! use v2t_lab::stats::Tally;
//! let stats = Tally::default().stats();
//! assert_eq!(stats.repeats, 0);
//! ```

pub mod bench_game;
pub mod bench_latency;
pub mod campaign;
pub mod cloud_mqtt;
pub mod cloud_run;
pub mod controllers;
pub mod demo;
pub mod ecu;
pub mod latency;
pub mod methods;
pub mod miss;
pub mod netdelay;
pub mod progress;
pub mod reach;
pub mod report;
pub mod sim;
pub mod stats;
pub mod steer;
pub mod sumo;
pub mod tradeoff;
pub mod vut;
pub mod world;

/// `f` of every job, in order, on up to 8 of the available cores (contiguous chunks). A panic in
/// `f` is raised again here, after every thread has ended: a chunk that went missing would shift
/// every later result against its job.
pub fn parallel_map<T: Sync, R: Send>(jobs: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).clamp(1, 8);
    let chunk = jobs.len().div_ceil(threads).max(1);
    let f = &f;
    std::thread::scope(|s| {
        let handles: Vec<_> =
            jobs.chunks(chunk).map(|part| s.spawn(move || part.iter().map(f).collect::<Vec<R>>())).collect();
        let mut out = Vec::with_capacity(jobs.len());
        let mut panicked = None;
        for h in handles {
            match h.join() {
                Ok(part) => out.extend(part),
                Err(e) => panicked = panicked.or(Some(e)),
            }
        }
        if let Some(e) = panicked {
            std::panic::resume_unwind(e);
        }
        out
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic)]
    use super::parallel_map;

    #[test]
    fn results_stay_with_their_jobs_and_a_panic_is_not_swallowed() {
        let jobs: Vec<u32> = (0..37).collect();
        assert_eq!(parallel_map(&jobs, |j| j * 2), jobs.iter().map(|j| j * 2).collect::<Vec<_>>());
        let caught = std::panic::catch_unwind(|| parallel_map(&jobs, |&j| if j == 3 { panic!("job 3") } else { j }));
        assert!(caught.is_err(), "a panicking job must not leave a shifted result behind");
    }
}
