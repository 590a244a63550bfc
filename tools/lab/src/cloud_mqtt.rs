//! The cloud regulator across a real MQTT broker, in real time: the BV side
//! ([`MqttCloudLink`], a [`CloudLink`] for [`crate::controllers::CloudRegulatedBv`]) publishes its
//! telemetry frames and takes the plans the cloud process ([`serve_regulator`]) publishes back.
//! Both ends read one clock: Unix time, with the test's start `epoch_ms` agreed beforehand (the
//! cloud starts the test, so it knows when). The simulation is paced to the wall clock: one run
//! takes as long as its scenario.
//!
//! Topics: the BV's telemetry topic carries its own state and the VUT's (telemetry of id
//! [`crate::controllers::VUT_ID`]); plans go down on the BV's plan topic, signed like every cloud frame.

use std::time::Duration;

use v2t_sim::scenario::Scenario;
use v2t_wire::link::topics;
use v2t_wire::mqtt::{LinkEvent, MqttLink, MqttSettings};

use crate::controllers::{CloudLink, CloudLinkStats, CloudRegulator};

pub use v2t_edge::uplink::unix_ms;

/// Why the link could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum CloudMqttError {
    /// The client.
    #[error("MQTT: {0}")]
    Mqtt(#[from] v2t_wire::mqtt::MqttError),
    /// No connection in time.
    #[error("no connection to the broker within {0:?}: {1}")]
    NotConnected(Duration, String),
}

/// Starts a client subscribed to `topic` and waits until it is connected and subscribed.
pub fn connect(settings: &MqttSettings, topic: String, within: Duration) -> Result<MqttLink, CloudMqttError> {
    let mqtt = MqttLink::start(settings, vec![topic])?;
    let deadline = std::time::Instant::now() + within;
    let mut last = String::from("no answer");
    loop {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        if left.is_zero() {
            mqtt.disconnect();
            return Err(CloudMqttError::NotConnected(within, last));
        }
        match mqtt.wait(left) {
            Some(LinkEvent::Connected) => return Ok(mqtt),
            Some(LinkEvent::Down(why)) => last = why,
            _ => {}
        }
    }
}

/// The BV's side of the link through a broker, paced to the wall clock.
#[derive(Debug)]
pub struct MqttCloudLink {
    mqtt: MqttLink,
    epoch_ms: u64,
    telemetry: String,
    plans: String,
}

impl MqttCloudLink {
    /// The link of BV `bv` of `fleet` through `mqtt` (connected, subscribed to the BV's plan
    /// topic), for a test that starts at Unix time `epoch_ms`.
    pub fn new(mqtt: MqttLink, fleet: &str, bv: &str, epoch_ms: u64) -> Self {
        Self {
            mqtt,
            epoch_ms,
            telemetry: topics::bv(fleet, bv, topics::TELEMETRY),
            plans: topics::bv(fleet, bv, topics::PLAN),
        }
    }
}

impl Drop for MqttCloudLink {
    fn drop(&mut self) {
        self.mqtt.disconnect();
    }
}

impl CloudLink for MqttCloudLink {
    fn epoch_ms(&self) -> u64 {
        self.epoch_ms
    }

    fn exchange(&mut self, t_s: f64, reports: Vec<Vec<u8>>, stats: &mut CloudLinkStats) -> Vec<(f64, Vec<u8>)> {
        // The simulation waits for the wall clock: this cycle happens at epoch + t.
        let due = crate::controllers::clock_ms(self.epoch_ms, t_s);
        let now = unix_ms();
        if due > now {
            std::thread::sleep(Duration::from_millis(due - now));
        }
        for r in reports {
            if self.mqtt.publish(&self.telemetry, r, false).is_err() {
                stats.up_lost += 1;
            }
        }
        let mut out = Vec::new();
        while let Some(ev) = self.mqtt.poll() {
            if let LinkEvent::Frame { topic, payload, arrived_ms } = ev
                && topic == self.plans
            {
                let at = (arrived_ms as f64 - self.epoch_ms as f64) / 1000.0;
                out.push((at.min(t_s), payload));
            }
        }
        out
    }
}

/// What the cloud process did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ServeStats {
    /// BV states heard.
    pub states: u64,
    /// Plans published.
    pub plans: u64,
    /// Decisions on stale states.
    pub stale: u64,
}

/// The cloud process: regulates BV `bv` of `fleet` in `scenario` with `cloud` on what arrives on
/// its telemetry topic through `mqtt` (connected, subscribed to that topic), publishing every plan
/// on its plan topic, from the test's start `epoch_ms` until the scenario's end (plus a second).
pub fn serve_regulator(
    cloud: &mut CloudRegulator,
    scenario: &Scenario,
    mqtt: &MqttLink,
    fleet: &str,
    bv: &str,
    epoch_ms: u64,
) -> ServeStats {
    let telemetry = topics::bv(fleet, bv, topics::TELEMETRY);
    let plans = topics::bv(fleet, bv, topics::PLAN);
    let until = crate::controllers::clock_ms(epoch_ms, scenario.duration_s + 1.0);
    let mut stats = ServeStats::default();
    loop {
        let now = unix_ms();
        if now >= until {
            break;
        }
        let Some(ev) = mqtt.wait(Duration::from_millis((until - now).min(100))) else { continue };
        let LinkEvent::Frame { topic, payload, .. } = ev else { continue };
        if topic != telemetry || !cloud.hear(&payload) {
            continue;
        }
        stats.states += 1;
        let now_s = (unix_ms() as f64 - epoch_ms as f64) / 1000.0;
        if let Some(frame) = cloud.decide(now_s, epoch_ms)
            && mqtt.publish(&plans, frame, false).is_ok()
        {
            stats.plans += 1;
        }
    }
    stats.stale = cloud.decisions().1;
    stats
}
