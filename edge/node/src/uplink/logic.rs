//! The pure part of the uplink: every cloud frame checked and turned into actions, and every
//! refusal either reported on its own (a genuine cloud frame, whose sender waits for the verdict)
//! or counted into one summary per second (anything else: garbage costs one count, not a message).

use std::collections::BTreeMap;

use v2t_wire::link::{self, Arrival, CloudBody, Command, LinkError, Receiver, Window};
use v2t_wire::mqtt::Dropped;
use v2t_wire::{ActivePrior, CampaignKnowledge, Header, SafetyAction};

use crate::campaign::Learned;
use crate::prior::{PriorChecks, from_upload};

/// What the uplink does with an accepted frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Hand this prior to the regulator and the tracker.
    Prior(Box<ActivePrior>),
    /// Ask the gateway for this.
    Safety(SafetyAction),
}

/// What happened to a frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// A genuine cloud frame, accepted or refused: its own event, with its sequence number.
    Verdict(Verdict),
    /// Anything else refused: one more count of its reason in the next summary.
    Counted(&'static str),
}

/// The verdict on a genuine cloud frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// What to do.
    pub actions: Vec<Action>,
    /// `accepted` or `refused`.
    pub verdict: &'static str,
    /// The frame's sequence number.
    pub seq: u64,
    /// What, or why not.
    pub detail: String,
}

impl Verdict {
    /// The event as one JSON line.
    pub fn event_json(&self, bv_id: &str, stamp_ms: u64) -> String {
        serde_json::json!({
            "bv_id": bv_id, "stamp_ms": stamp_ms, "seq": self.seq, "verdict": self.verdict, "detail": self.detail
        })
        .to_string()
    }
}

/// The reason of a refused frame, as it is counted.
pub fn reason_kind(e: &LinkError) -> &'static str {
    match e {
        LinkError::Malformed(_) => "malformed",
        LinkError::Version { .. } => "other link version",
        LinkError::Signature => "bad signature",
        LinkError::Decode(_) => "undecodable body",
        LinkError::OtherFleet { .. } => "other fleet",
        LinkError::WrongTopic { .. } => "wrong topic",
        LinkError::NotForMe { .. } => "addressed to another BV",
        LinkError::Replay { .. } => "replay",
        LinkError::Stale { .. } => "stale",
        LinkError::Future { .. } => "from the future",
        LinkError::Encode(_) => "unencodable",
    }
}

/// Counts of refused frames by reason, reported once per period.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RefusalTally {
    counts: BTreeMap<&'static str, u64>,
}

impl RefusalTally {
    /// One more frame refused for `reason`.
    pub fn add(&mut self, reason: &'static str) {
        *self.counts.entry(reason).or_default() += 1;
    }

    /// The messages the MQTT thread dropped before they reached the node.
    pub fn add_dropped(&mut self, d: &Dropped) {
        for (reason, n) in &d.screened {
            *self.counts.entry(reason).or_default() += n;
        }
        for (reason, n) in [
            ("longer than a frame", d.oversize),
            ("command queue full", d.urgent_full),
            ("prior queue full", d.bulk_full),
        ] {
            if n > 0 {
                *self.counts.entry(reason).or_default() += n;
            }
        }
    }

    /// Whether nothing was refused since the last summary.
    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    /// The summary event of the counts over `period_s` (one JSON line, no sequence number: no
    /// sender waits for it), and resets them.
    pub fn take_event(&mut self, bv_id: &str, stamp_ms: u64, period_s: f64) -> String {
        let counts = std::mem::take(&mut self.counts);
        let total: u64 = counts.values().sum();
        let parts: Vec<String> = counts.iter().map(|(r, n)| format!("{n} {r}")).collect();
        let detail = format!("{total} frames refused in {period_s:.1} s: {}", parts.join(", "));
        serde_json::json!({
            "bv_id": bv_id, "stamp_ms": stamp_ms, "seq": null, "verdict": "refused", "detail": detail, "counts": counts
        })
        .to_string()
    }
}

/// The pure part of the uplink: checks every cloud frame and turns it into actions.
#[derive(Debug)]
pub struct UplinkLogic {
    rx: Receiver,
    checks: PriorChecks,
    active: Option<ActivePrior>,
    /// A start was accepted since the active prior came or the BV was last armed: the run is on.
    started: bool,
}

impl UplinkLogic {
    /// The logic of BV `bv_id` of `fleet`, trusting `key`.
    pub fn new(key: link::VerifyingKey, fleet: &str, bv_id: &str, window: Window, checks: PriorChecks) -> Self {
        Self { rx: Receiver::new(key, fleet, bv_id, window), checks, active: None, started: false }
    }

    /// Refuses every sequence number up to `seq` from now on (the state a previous run left).
    pub fn resume_after(&mut self, seq: u64) {
        self.rx.resume_after(seq);
    }

    /// The last accepted sequence number.
    pub fn last_seq(&self) -> Option<u64> {
        self.rx.last_seq()
    }

    /// The prior handed to the regulator last.
    pub fn active(&self) -> Option<&ActivePrior> {
        self.active.as_ref()
    }

    /// One frame that arrived on `arrival` at Unix time `arrived_ms`, handled at Unix time `now_ms`
    /// and monotonic `mono_ns`.
    pub fn on_frame(&mut self, frame: &[u8], arrival: Arrival, arrived_ms: u64, now_ms: u64, mono_ns: u64) -> Outcome {
        let msg = match self.rx.open(frame, arrival, arrived_ms) {
            Ok(m) => m,
            Err(refusal) => {
                return match refusal.genuine_seq {
                    Some(seq) => Outcome::Verdict(Verdict {
                        actions: Vec::new(),
                        verdict: "refused",
                        seq,
                        detail: format!("frame: {}", refusal.reason),
                    }),
                    None => Outcome::Counted(reason_kind(&refusal.reason)),
                };
            }
        };
        let seq = msg.seq;
        let refused =
            |detail: String| Outcome::Verdict(Verdict { actions: Vec::new(), verdict: "refused", seq, detail });
        let ok = |actions: Vec<Action>, detail: String| {
            Outcome::Verdict(Verdict { actions, verdict: "accepted", seq, detail })
        };
        match msg.body {
            CloudBody::Prior(up) => match from_upload(&up, now_ms, &self.checks, mono_ns) {
                Ok(prior) => {
                    self.active = Some(prior.clone());
                    self.started = false;
                    ok(vec![Action::Prior(Box::new(prior))], format!("prior {} (seq {seq})", up.prior_id))
                }
                Err(e) => refused(e.to_string()),
            },
            CloudBody::Command(Command::Arm) => {
                self.started = false;
                // Armed for a run: with a prior active, the regulator starts its run over (the
                // prior again as the next run; what it learned comes back only with the cloud's
                // `campaign send`).
                let Some(active) = self.active.as_mut() else {
                    return ok(vec![Action::Safety(SafetyAction::Reset)], format!("arm (seq {seq}): gate reset"));
                };
                active.run += 1;
                active.header = Header { seq: active.header.seq + 1, stamp_ns: mono_ns };
                let detail = format!("arm (seq {seq}): gate reset, run {} of prior {}", active.run, active.prior_id);
                ok(vec![Action::Safety(SafetyAction::Reset), Action::Prior(Box::new(active.clone()))], detail)
            }
            CloudBody::Command(Command::Start) => {
                self.started = true;
                ok(vec![Action::Safety(SafetyAction::Engage)], format!("start (seq {seq}): engage"))
            }
            CloudBody::Command(Command::Abort) => {
                ok(vec![Action::Safety(SafetyAction::MinimalRiskStop)], format!("abort (seq {seq}): minimal-risk stop"))
            }
            CloudBody::Command(Command::SetTarget(target)) => {
                let Some(active) = self.active.as_mut() else {
                    return refused("set target: no active prior".into());
                };
                active.set_target(target);
                active.header = Header { seq: active.header.seq + 1, stamp_ns: mono_ns };
                let prior = active.clone();
                ok(vec![Action::Prior(Box::new(prior))], format!("set target (seq {seq}): {target}"))
            }
            // This runtime regulates onboard: a cloud plan has no place here (and its topic is
            // never subscribed).
            CloudBody::Plan(_) => refused("a cloud plan: this BV regulates onboard".into()),
            CloudBody::Campaign(up) => {
                let Some(active) = self.active.as_mut() else {
                    return refused(format!("campaign knowledge for prior {}: no active prior", up.prior_id));
                };
                if up.prior_id != active.prior_id {
                    return refused(format!(
                        "campaign knowledge for prior {}: the active prior is {}",
                        up.prior_id, active.prior_id
                    ));
                }
                if self.started {
                    // It starts the regulator's identification of the VUT over: for the next run.
                    return refused(format!(
                        "campaign knowledge for prior {}: the run has started (send it before `start`)",
                        up.prior_id
                    ));
                }
                match with_campaign(active, &up, seq, mono_ns) {
                    Ok((prior, learned)) => {
                        *active = prior.clone();
                        ok(
                            vec![Action::Prior(Box::new(prior))],
                            format!("campaign (seq {seq}): aim {}, {}", up.aim, learned.summary()),
                        )
                    }
                    Err(e) => refused(e),
                }
            }
        }
    }
}

/// The active prior `active` as it is published with the campaign knowledge `up` of the cloud
/// message `seq` (at monotonic `mono_ns`): aimed at its aim, its block set, the next header
/// sequence; with what the regulator will take of it. The error says which field is refused.
pub fn with_campaign(
    active: &ActivePrior,
    up: &link::CampaignUpload,
    seq: u64,
    mono_ns: u64,
) -> Result<(ActivePrior, Learned), String> {
    let knowledge = CampaignKnowledge::from_upload(up, seq).map_err(|e| e.to_string())?;
    let learned = Learned::from_knowledge(&knowledge).map_err(|e| e.to_string())?;
    let mut prior = active.clone();
    prior.set_target(up.aim);
    prior.campaign = knowledge;
    prior.header = Header { seq: active.header.seq + 1, stamp_ns: mono_ns };
    Ok((prior, learned))
}

/// What the regulator's lesson `msg` says, as the BV `bv_id` reports it to the cloud at Unix
/// `stamp_ms`. The error names what does not decode.
pub fn run_learned(msg: &v2t_wire::RunLearnedMsg, bv_id: &str, stamp_ms: u64) -> Result<link::RunLearned, String> {
    use v2t_wire::Code as _;
    let style = v2t_wire::StyleCode::from_code(msg.style).map_err(|e| e.to_string())?;
    let aim = v2t_model::Target::new(msg.tau_s, style.into()).map_err(|e| e.to_string())?;
    let learned = Learned::from_knowledge(&msg.learned).map_err(|e| e.to_string())?;
    let up = learned.upload(msg.prior_id, aim);
    Ok(link::RunLearned {
        bv_id: bv_id.to_owned(),
        prior_id: msg.prior_id,
        stamp_ms,
        aim,
        started_with_route: msg.started_with_route == 1,
        started_with_reaction: msg.started_with_reaction == 1,
        route: up.route,
        reaction: up.reaction,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use link::{CloudMessage, SigningKey};
    use v2t_wire::{Code as _, StyleCode};

    fn setup() -> (UplinkLogic, SigningKey, link::PriorUpload) {
        let (up, checks) = crate::prior::fixtures::upload("semantics_cut_in.json", 5, (0, 100_000));
        let key = SigningKey::from_bytes(&[3; 32]);
        let logic = UplinkLogic::new(key.verifying_key(), "pg", "bv1", Window::default(), checks);
        (logic, key, up)
    }

    fn yield_3s() -> v2t_model::Target {
        v2t_model::Target::new(3.0, v2t_model::Style::Yield).unwrap()
    }

    fn frame(key: &SigningKey, seq: u64, body: CloudBody) -> Vec<u8> {
        let m = CloudMessage { fleet: "pg".into(), bv_id: "bv1".into(), seq, issued_ms: 50_000, body };
        link::seal(&m, key).unwrap()
    }

    fn verdict(o: Outcome) -> Verdict {
        match o {
            Outcome::Verdict(v) => v,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn priors_and_commands_become_actions_and_refusals_say_why() {
        let (mut logic, key, up) = setup();
        let set = |seq| frame(&key, seq, CloudBody::Command(Command::SetTarget(yield_3s())));
        let o = verdict(logic.on_frame(&set(1), Arrival::Command, 50_000, 50_000, 1));
        assert_eq!((o.verdict, o.actions.len(), o.seq), ("refused", 0, 1));
        assert!(o.detail.contains("no active prior"), "{}", o.detail);

        let o =
            verdict(logic.on_frame(&frame(&key, 2, CloudBody::Prior(up.clone())), Arrival::Prior, 50_000, 50_000, 7));
        assert_eq!(o.verdict, "accepted", "{}", o.detail);
        let Some(Action::Prior(p)) = o.actions.first() else { panic!("{o:?}") };
        assert_eq!((p.prior_id, p.header.stamp_ns, p.tau_s), (5, 7, up.prior.target.tau_s()));
        assert!(o.event_json("bv1", 9).contains("\"verdict\":\"accepted\""));

        let o = verdict(logic.on_frame(&set(3), Arrival::Command, 50_000, 50_000, 8));
        let Some(Action::Prior(q)) = o.actions.first() else { panic!("{o:?}") };
        assert_eq!((q.tau_s, q.style, q.header.seq), (3.0, StyleCode::Yield.code(), p.header.seq + 1));
        assert_eq!(q.bv_path, p.bv_path, "only the target changes");

        for (seq, cmd, action) in [
            (5, Command::Arm, SafetyAction::Reset),
            (6, Command::Start, SafetyAction::Engage),
            (7, Command::Abort, SafetyAction::MinimalRiskStop),
        ] {
            let o = verdict(logic.on_frame(
                &frame(&key, seq, CloudBody::Command(cmd)),
                Arrival::Command,
                50_000,
                50_000,
                9,
            ));
            assert_eq!(o.actions.first(), Some(&Action::Safety(action)));
            // Armed with a prior active, the prior goes again as its next run.
            let next_run =
                matches!(cmd, Command::Arm).then(|| Action::Prior(Box::new(logic.active().unwrap().clone())));
            assert_eq!(o.actions.get(1), next_run.as_ref(), "{cmd:?}");
            assert_eq!(o.actions.len(), 1 + usize::from(next_run.is_some()));
        }
        // A replay of a genuine frame is a verdict the sender can match; garbage is only counted.
        let o = verdict(logic.on_frame(
            &frame(&key, 7, CloudBody::Command(Command::Start)),
            Arrival::Command,
            50_000,
            50_000,
            9,
        ));
        assert!(o.detail.contains("replay") && o.actions.is_empty(), "{}", o.detail);
        assert_eq!(logic.on_frame(b"garbage", Arrival::Command, 50_000, 50_000, 9), Outcome::Counted("malformed"));
        let foreign = frame(&SigningKey::from_bytes(&[4; 32]), 9, CloudBody::Command(Command::Abort));
        assert_eq!(logic.on_frame(&foreign, Arrival::Command, 50_000, 50_000, 9), Outcome::Counted("bad signature"));
        assert_eq!(logic.last_seq(), Some(7));
    }

    #[test]
    fn campaign_knowledge_joins_the_active_prior_before_the_run_starts() {
        use crate::campaign::Learned;
        use v2t_game::route_speed::RouteSpeed;
        let (mut logic, key, up) = setup();
        let rush = v2t_model::Target::new(2.5, v2t_model::Style::Rush).unwrap();
        let learned = Learned {
            route: Some(RouteSpeed { step_m: 2.0, speeds_mps: vec![8.0, 7.5, 6.0, 4.3], runs: 2 }),
            ..Learned::default()
        };
        let send = |logic: &mut UplinkLogic, seq, up: link::CampaignUpload| {
            verdict(logic.on_frame(&frame(&key, seq, CloudBody::Campaign(up)), Arrival::Prior, 50_000, 50_000, 20))
        };
        let o = send(&mut logic, 1, learned.upload(5, rush));
        assert!(o.verdict == "refused" && o.detail.contains("no active prior"), "{}", o.detail);
        let o = verdict(logic.on_frame(&frame(&key, 2, CloudBody::Prior(up)), Arrival::Prior, 50_000, 50_000, 7));
        let Some(Action::Prior(p)) = o.actions.first() else { panic!("{o:?}") };
        assert_eq!(p.campaign.seq, 0, "a prior is uploaded knowing nothing");
        let o = send(&mut logic, 3, learned.upload(6, rush));
        assert!(o.verdict == "refused" && o.detail.contains("the active prior is 5"), "{}", o.detail);
        // Refused by name: the regulator's own rule (a route rests on at least one run).
        let mut bad = learned.upload(5, rush);
        bad.route.as_mut().unwrap().runs = 0;
        let o = send(&mut logic, 4, bad);
        assert!(o.verdict == "refused" && o.detail.contains("campaign.route.runs"), "{}", o.detail);
        // On a wrong topic it is not even opened.
        let wrong = frame(&key, 5, CloudBody::Campaign(learned.upload(5, rush)));
        assert_eq!(logic.on_frame(&wrong, Arrival::Command, 50_000, 50_000, 20), Outcome::Counted("wrong topic"));

        let o = send(&mut logic, 6, learned.upload(5, rush));
        assert_eq!(o.verdict, "accepted", "{}", o.detail);
        assert!(o.detail.contains("route over 2 run(s), 6 m"), "{}", o.detail);
        let Some(Action::Prior(q)) = o.actions.first() else { panic!("{o:?}") };
        assert_eq!((q.prior_id, q.header.seq, q.campaign.seq), (5, p.header.seq + 1, 6));
        assert_eq!(q.target().unwrap(), rush);
        assert_eq!(Learned::from_knowledge(&q.campaign).unwrap(), learned);
        assert_eq!(q.bv_path, p.bv_path, "the prior is the same");

        // Once started, the run keeps what it started with; armed again, the next run may learn.
        let cmd = |logic: &mut UplinkLogic, seq, c| {
            verdict(logic.on_frame(&frame(&key, seq, CloudBody::Command(c)), Arrival::Command, 50_000, 50_000, 21))
        };
        assert_eq!(cmd(&mut logic, 7, Command::Start).verdict, "accepted");
        let o = send(&mut logic, 8, learned.upload(5, rush));
        assert!(o.verdict == "refused" && o.detail.contains("the run has started"), "{}", o.detail);
        // Armed again: the regulator starts its next run of the prior, with what it knew.
        let o = cmd(&mut logic, 9, Command::Arm);
        assert_eq!(o.verdict, "accepted");
        assert!(o.detail.contains("run 1 of prior 5"), "{}", o.detail);
        let [Action::Safety(SafetyAction::Reset), Action::Prior(r)] = o.actions.as_slice() else { panic!("{o:?}") };
        assert_eq!((r.prior_id, r.run, r.header.seq, &r.campaign), (5, 1, q.header.seq + 1, &q.campaign));
        assert_eq!(send(&mut logic, 10, learned.upload(5, rush)).verdict, "accepted");
    }

    #[test]
    fn refusals_add_up_into_one_summary() {
        let mut t = RefusalTally::default();
        assert!(t.is_empty());
        for _ in 0..3 {
            t.add("malformed");
        }
        t.add("bad signature");
        t.add_dropped(&Dropped { oversize: 2, ..Dropped::default() });
        let e: serde_json::Value = serde_json::from_str(&t.take_event("bv1", 5, 1.0)).unwrap();
        assert_eq!(e["seq"], serde_json::Value::Null);
        assert_eq!(e["counts"]["malformed"], 3);
        assert_eq!(e["detail"], "6 frames refused in 1.0 s: 1 bad signature, 2 longer than a frame, 3 malformed");
        assert!(t.is_empty());
    }
}
