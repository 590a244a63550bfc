//! One run with the BV's regulator in the cloud: across a simulated network in the same process,
//! or behind any other [`CloudLink`] (a broker and a cloud process, [`crate::cloud_mqtt`]). What
//! `video2track sim --regulated --network|--cloud-broker` runs; the CLI only reads its options.

use v2t_game::regulator::RegulatorParams;
use v2t_sim::bv::BvController;
use v2t_sim::network::NetworkSettings;
use v2t_sim::runner::RunOutcome;
use v2t_sim::scenario::Scenario;
use v2t_wire::link::VerifyingKey;

use crate::controllers::{CloudBvError, CloudLink, CloudLinkStats, CloudRegulatedBv, RegulatedBv};
use crate::vut::Vut;

/// Where the cloud regulator's plans come from.
#[derive(Debug)]
pub enum CloudAt<'a> {
    /// A regulator in this process behind a simulated network (its draws seeded by the run's seed).
    Network(&'a NetworkSettings),
    /// A regulator behind `link`, its plans signed with the key `key` verifies, for BV `bv_id` of
    /// `fleet`.
    Link {
        /// The link.
        link: Box<dyn CloudLink>,
        /// The cloud's public key.
        key: Box<VerifyingKey>,
        /// The fleet (test session).
        fleet: &'a str,
        /// The BV's id on the link.
        bv_id: &'a str,
    },
}

/// Why a cloud-regulated run did not run.
#[derive(Debug, thiserror::Error)]
pub enum CloudRunError {
    /// The card has other than one BV.
    #[error("the cloud regulator drives one BV; the card {scenario} has {bvs}")]
    OneBv {
        /// The card's name.
        scenario: String,
        /// Its BVs.
        bvs: usize,
    },
    /// The regulated BV could not be built.
    #[error(transparent)]
    Bv(#[from] CloudBvError),
    /// The world could not run it.
    #[error(transparent)]
    Run(#[from] v2t_sim::runner::RunError),
}

/// One run of `scenario` against `vut` with its BV regulated in the cloud with `settings` (the
/// scenario's vehicle limits added): the outcome and what the link did.
pub fn cloud_regulated_run(
    settings: &RegulatorParams,
    scenario: &Scenario,
    vut: &Vut<'_>,
    seed: u64,
    at: CloudAt<'_>,
) -> Result<(RunOutcome, CloudLinkStats), CloudRunError> {
    if scenario.bvs.len() != 1 {
        return Err(CloudRunError::OneBv { scenario: scenario.name.clone(), bvs: scenario.bvs.len() });
    }
    let params = RegulatedBv::params_for(settings, scenario, 0);
    let bv = match at {
        CloudAt::Network(network) => CloudRegulatedBv::new(params, scenario, 0, network, seed)?,
        CloudAt::Link { link, key, fleet, bv_id } => {
            CloudRegulatedBv::with_link(params, scenario, 0, link, *key, fleet, bv_id)?
        }
    };
    let report = bv.link_report();
    let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(bv)];
    let outcome = vut.run(scenario, &mut bvs, seed)?;
    Ok((outcome, report.get()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2t_sim::vut::VutModel;

    #[test]
    fn a_card_runs_with_its_bv_regulated_across_a_simulated_network() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let sc = v2t_sim::files::load_scenario(&root.join("config/scenarios/left_turn_basic.toml")).unwrap();
        let network: NetworkSettings = v2t_files::load_toml(&root.join("config/network/lte.toml")).unwrap();
        let vut = Vut::Builtin(VutModel::IdmNormal);
        let (out, link) =
            cloud_regulated_run(&RegulatorParams::default(), &sc, &vut, 3, CloudAt::Network(&network)).unwrap();
        assert!(out.result.collision.is_none() && out.result.pet_min_s.is_some());
        assert!(link.cycles > 100 && link.decisions > 50 && link.plans_accepted > 50, "{link:?}");
        let mut two = sc.clone();
        two.bvs.push(two.bvs[0].clone());
        let err = cloud_regulated_run(&RegulatorParams::default(), &two, &vut, 3, CloudAt::Network(&network));
        assert!(matches!(err, Err(CloudRunError::OneBv { bvs: 2, .. })));
    }
}
