//! What a test campaign has learned of the VUT, on the BV: the aim of the next run, what earlier
//! runs showed about reach, how the VUT drove its route and how it was identified to react
//! (`v2t_game::campaign`'s memory of one test), carried by a signed
//! [`CampaignUpload`], kept with the active prior
//! ([`CampaignKnowledge`]) and given to the regulator before the run starts ([`Learned::apply`]).
//!
//! The lab's campaigns give it to their regulated BVs through the same conversions (upload → the
//! prior's block → [`Learned`] → the regulator), so what they measure is what the vehicle does.

use v2t_game::reaction::{HYPOTHESES, ReactionPosterior};
use v2t_game::regulation::Regulation;
use v2t_game::regulator::{BelowReach, BelowReachCause};
use v2t_game::route_speed::{ROUTE_MAX_POINTS, RouteSpeed};
use v2t_model::Target;
use v2t_model::validate::{Validate as _, ValidationError};
use v2t_wire::link::{CampaignUpload, KnownBelowReach, LearnedReaction, LearnedRoute};
use v2t_wire::{BelowReachCode, CampaignKnowledge, Code as _, MAX_REACTION_HYPOTHESES, MAX_ROUTE_POINTS};

// The wire's capacities hold what the regulator keeps.
const _: () = assert!(ROUTE_MAX_POINTS <= MAX_ROUTE_POINTS && HYPOTHESES <= MAX_REACTION_HYPOTHESES);

/// The wire code of a below-reach cause.
pub fn below_reach_code(c: BelowReachCause) -> BelowReachCode {
    match c {
        BelowReachCause::VutWaits => BelowReachCode::VutWaits,
        BelowReachCause::Campaign => BelowReachCode::Campaign,
        BelowReachCause::OrderRefused => BelowReachCode::OrderRefused,
    }
}

fn below_reach_cause(c: BelowReachCode) -> BelowReachCause {
    match c {
        BelowReachCode::VutWaits => BelowReachCause::VutWaits,
        BelowReachCode::Campaign => BelowReachCause::Campaign,
        BelowReachCode::OrderRefused => BelowReachCause::OrderRefused,
    }
}

/// What a campaign has learned of the VUT for one run, in the regulator's terms, checked by its
/// rules. [`Learned::default`]: nothing (a run against a VUT the regulator has not seen).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Learned {
    /// What earlier runs showed about reach.
    pub known: Option<BelowReach>,
    /// How the VUT drove its route.
    pub route: Option<RouteSpeed>,
    /// How it was identified to react (the prior of this run's identification).
    pub reaction: Option<ReactionPosterior>,
}

impl Learned {
    /// What the active prior's block holds, checked by the regulator's rules (the error names the
    /// field under `campaign`); nothing when the block is empty.
    pub fn from_knowledge(k: &CampaignKnowledge) -> Result<Self, ValidationError> {
        let within = |e: ValidationError| e.within("campaign");
        let known = match k.below_reach() {
            Some((code, bound)) => {
                let cause = BelowReachCode::from_code(code)
                    .map_err(|e| within(ValidationError::new("below_reach", e.to_string())))?;
                if let Some(b) = bound {
                    v2t_model::validate::in_range("pet_bound_s", b, 0.0, 60.0).map_err(within)?;
                }
                Some(BelowReach { cause: below_reach_cause(cause), pet_bound_s: bound })
            }
            None => None,
        };
        let route = k
            .route()
            .map(|(step_m, runs, speeds)| RouteSpeed { step_m, speeds_mps: speeds.to_vec(), runs })
            .map(|r| r.validate().map(|()| r).map_err(|e| within(e.within("route"))))
            .transpose()?;
        let reaction = k
            .reaction()
            .map(|(p, informative_cycles)| ReactionPosterior { probabilities: p.to_vec(), informative_cycles })
            .map(|r| r.validate().map(|()| r).map_err(|e| within(e.within("reaction"))))
            .transpose()?;
        Ok(Self { known, route, reaction })
    }

    /// The upload that carries this to the BV running the prior `prior_id`, aiming at `aim`.
    pub fn upload(&self, prior_id: u64, aim: Target) -> CampaignUpload {
        CampaignUpload {
            prior_id,
            aim,
            below_reach: self
                .known
                .map(|b| KnownBelowReach { cause: below_reach_code(b.cause).code(), pet_bound_s: b.pet_bound_s }),
            route: self.route.as_ref().map(|r| LearnedRoute {
                step_m: r.step_m,
                runs: r.runs,
                speeds_mps: r.speeds_mps.clone(),
            }),
            reaction: self.reaction.as_ref().map(|r| LearnedReaction {
                probabilities: r.probabilities.clone(),
                informative_cycles: r.informative_cycles,
            }),
        }
    }

    /// What `up` says, as the BV takes it: through the block it keeps with the prior (the wire's
    /// bounds, then the regulator's rules).
    pub fn from_upload(up: &CampaignUpload) -> Result<Self, ValidationError> {
        let k = CampaignKnowledge::from_upload(up, 1).map_err(|e| ValidationError::new("campaign", e.to_string()))?;
        Self::from_knowledge(&k)
    }

    /// Gives it to `regulation` for the run around its context, aiming at `aim`: the aim and the
    /// reach, the route (none: the follower keeps the VUT's current speed), the prior of the
    /// reaction's identification (none: the default; it starts the run's identification over).
    pub fn apply(&self, regulation: &mut Regulation, aim: Target) -> Result<(), ValidationError> {
        regulation.set_route_speed(self.route.clone())?;
        regulation.set_reaction_prior(self.reaction.as_ref())?;
        regulation.aim(aim, self.known);
        Ok(())
    }

    /// In words, for the BV's verdict and log.
    pub fn summary(&self) -> String {
        let mut parts = Vec::new();
        if let Some(r) = &self.route {
            parts.push(format!(
                "route over {} run(s), {:.0} m",
                r.runs,
                (r.speeds_mps.len().saturating_sub(1)) as f64 * r.step_m
            ));
        }
        if let Some(r) = &self.reaction {
            parts.push(format!("reaction prior from {} informative cycles", r.informative_cycles));
        }
        if let Some(b) = &self.known {
            parts.push(match b.pet_bound_s {
                Some(p) => format!("below reach ({:?}, ≥ {p:.2} s)", b.cause),
                None => format!("below reach ({:?})", b.cause),
            });
        }
        if parts.is_empty() { "nothing learned yet".into() } else { parts.join(", ") }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use v2t_model::Style;

    fn learned(speeds: Vec<f64>, p_none: f64, bound: Option<f64>) -> Learned {
        let mut probabilities = vec![(1.0 - p_none) / (HYPOTHESES - 1) as f64; HYPOTHESES];
        probabilities[0] = p_none;
        Learned {
            known: Some(BelowReach { cause: BelowReachCause::Campaign, pet_bound_s: bound }),
            route: Some(RouteSpeed { step_m: 2.0, speeds_mps: speeds, runs: 3 }),
            reaction: Some(ReactionPosterior { probabilities, informative_cycles: 412 }),
        }
    }

    proptest! {
        /// What the cloud sends is what the regulator gets, to the bit, through the block the BV
        /// keeps with its prior.
        #[test]
        fn what_the_cloud_sends_is_what_the_regulator_gets(
            speeds in prop::collection::vec(0.0..70.0f64, 2..=ROUTE_MAX_POINTS),
            p_none in 0.0..1.0f64,
            bound in prop::option::of(0.0..60.0f64),
        ) {
            let l = learned(speeds, p_none, bound);
            let up = l.upload(7, Target::new(2.5, Style::Rush).unwrap());
            prop_assert_eq!(Learned::from_upload(&up).unwrap(), l);
        }
    }

    #[test]
    fn nothing_learned_is_an_empty_block_and_bad_parts_are_refused_by_name() {
        let aim = Target::new(2.0, Style::Yield).unwrap();
        let none = Learned::default().upload(3, aim);
        assert_eq!(Learned::from_upload(&none).unwrap(), Learned::default());
        assert_eq!(CampaignKnowledge::from_upload(&none, 5).unwrap().route(), None);
        // The wire's bounds first: a speed out of range, a route of one point.
        let mut bad = learned(vec![8.0; 10], 0.5, None).upload(3, aim);
        bad.route.as_mut().unwrap().speeds_mps[4] = f64::NAN;
        let e = Learned::from_upload(&bad).unwrap_err().to_string();
        assert!(e.contains("route.speeds_mps[4]") && e.contains("[0, 70]"), "{e}");
        bad.route.as_mut().unwrap().speeds_mps = vec![8.0];
        assert!(Learned::from_upload(&bad).unwrap_err().to_string().contains("2 to 501"));
        // Then the regulator's: a posterior over another number of hypotheses, or not summing to 1.
        let mut bad = learned(vec![8.0; 10], 0.5, None).upload(3, aim);
        bad.reaction.as_mut().unwrap().probabilities.truncate(5);
        let e = Learned::from_upload(&bad).unwrap_err().to_string();
        assert!(e.contains("campaign.reaction.probabilities") && e.contains("37"), "{e}");
        let mut bad = learned(vec![8.0; 10], 0.5, None).upload(3, aim);
        bad.reaction.as_mut().unwrap().probabilities[0] = 1.0;
        assert!(Learned::from_upload(&bad).unwrap_err().to_string().contains("sum to 1"));
        let mut bad = learned(vec![8.0; 10], 0.5, None).upload(3, aim);
        bad.route.as_mut().unwrap().runs = 0;
        assert!(Learned::from_upload(&bad).unwrap_err().to_string().contains("campaign.route.runs"));
        let mut bad = learned(vec![8.0; 10], 0.5, None).upload(3, aim);
        bad.below_reach.as_mut().unwrap().cause = 9;
        assert!(Learned::from_upload(&bad).unwrap_err().to_string().contains("below_reach.cause"));
    }
}
