//! Opening the onboard services. Every process opens a service with the same settings (they must
//! match, or iceoryx2 refuses), so they are all chosen here, per service.

use std::fmt::Debug;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use iceoryx2::node::Node;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::Service;
use v2t_wire::services;

use crate::error::EdgeError;

/// Queue settings of one publish-subscribe service.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    /// Samples a late subscriber receives on connecting.
    pub history: usize,
    /// Samples a subscriber keeps before the oldest is overwritten.
    pub buffer: usize,
}

/// The settings of service `leaf`.
pub fn qos(leaf: &str) -> Qos {
    match leaf {
        // Every transmission is a latency sample for the bench, and a CAN frame must not be lost.
        services::GATE | services::CAN_TX | services::CAN_RX => Qos { history: 0, buffer: 256 },
        // A node that (re)starts needs the prior and the latest safety request at once.
        services::PRIOR | services::SAFETY => Qos { history: 1, buffer: 2 },
        services::HEARTBEAT => Qos { history: 0, buffer: 64 },
        _ => Qos { history: 1, buffer: 8 },
    }
}

/// Publishers per service: the producer, a restarted producer while the dead one is not yet
/// cleaned up, tools.
const MAX_PUBLISHERS: usize = 8;
const MAX_SUBSCRIBERS: usize = 8;
const MAX_NODES: usize = 24;

/// An iceoryx2 node of one BV's runtime, with its service namespace.
#[derive(Debug)]
pub struct Bus<S: Service> {
    node: Node<S>,
    namespace: String,
}

impl<S: Service> Bus<S> {
    /// A node called `name` in `namespace` (e.g. `v2t/bv1`).
    pub fn new(name: &str, namespace: &str) -> Result<Self, EdgeError> {
        let node_name = NodeName::new(name).map_err(|e| EdgeError::ipc("node name", name, e))?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .signal_handling_mode(SignalHandlingMode::HandleTerminationRequests)
            .create::<S>()
            .map_err(|e| EdgeError::ipc("create node", name, e))?;
        Ok(Self { node, namespace: namespace.to_owned() })
    }

    /// The iceoryx2 node.
    pub fn node(&self) -> &Node<S> {
        &self.node
    }

    /// The namespace.
    pub fn namespace(&self) -> &str {
        &self.namespace
    }

    fn service_name(&self, leaf: &str) -> Result<(String, ServiceName), EdgeError> {
        let full = services::name(&self.namespace, leaf);
        let name = ServiceName::new(&full).map_err(|e| EdgeError::ipc("service name", &full, e))?;
        Ok((full, name))
    }

    fn pubsub<T: Debug + ZeroCopySend + 'static>(
        &self,
        leaf: &str,
    ) -> Result<(String, iceoryx2::service::port_factory::publish_subscribe::PortFactory<S, T, ()>), EdgeError> {
        let (full, name) = self.service_name(leaf)?;
        let q = qos(leaf);
        let factory = self
            .node
            .service_builder(&name)
            .publish_subscribe::<T>()
            .history_size(q.history)
            .subscriber_max_buffer_size(q.buffer.max(q.history))
            .max_publishers(MAX_PUBLISHERS)
            .max_subscribers(MAX_SUBSCRIBERS)
            .max_nodes(MAX_NODES)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(|e| EdgeError::ipc("open service", &full, e))?;
        Ok((full, factory))
    }

    /// A publisher on `leaf`.
    pub fn publisher<T: Debug + ZeroCopySend + 'static>(&self, leaf: &str) -> Result<Publisher<S, T, ()>, EdgeError> {
        let (full, factory) = self.pubsub::<T>(leaf)?;
        factory.publisher_builder().create().map_err(|e| EdgeError::ipc("create publisher", &full, e))
    }

    /// A subscriber on `leaf`.
    pub fn subscriber<T: Debug + ZeroCopySend + 'static>(&self, leaf: &str) -> Result<Subscriber<S, T, ()>, EdgeError> {
        let (full, factory) = self.pubsub::<T>(leaf)?;
        factory.subscriber_builder().create().map_err(|e| EdgeError::ipc("create subscriber", &full, e))
    }

    fn event(&self, leaf: &str) -> Result<(String, iceoryx2::service::port_factory::event::PortFactory<S>), EdgeError> {
        let (full, name) = self.service_name(leaf)?;
        let factory = self
            .node
            .service_builder(&name)
            .event()
            .max_notifiers(MAX_PUBLISHERS)
            .max_listeners(MAX_SUBSCRIBERS)
            .max_nodes(MAX_NODES)
            .open_or_create()
            .map_err(|e| EdgeError::ipc("open event", &full, e))?;
        Ok((full, factory))
    }

    /// A notifier on the event service `leaf` (one of `services::WAKES`).
    pub fn notifier(&self, leaf: &str) -> Result<Notifier<S>, EdgeError> {
        let (full, factory) = self.event(leaf)?;
        factory.notifier_builder().create().map_err(|e| EdgeError::ipc("create notifier", &full, e))
    }

    /// A listener on the event service `leaf` (one of `services::WAKES`).
    pub fn listener(&self, leaf: &str) -> Result<Listener<S>, EdgeError> {
        let (full, factory) = self.event(leaf)?;
        factory.listener_builder().create().map_err(|e| EdgeError::ipc("create listener", &full, e))
    }

    /// Whether SIGINT/SIGTERM arrived.
    pub fn terminating(&self) -> bool {
        terminating()
    }

    /// Sleeps up to `timeout` unless a termination was requested: `false` means stop.
    pub fn wait(&self, timeout: Duration) -> bool {
        if terminating() {
            return false;
        }
        if self.node.wait(timeout).is_ok() {
            return true;
        }
        TERMINATING.store(true, Ordering::Relaxed);
        false
    }
}

/// Makes `path` (normally `config/iceoryx2.toml`) this process's iceoryx2 configuration; call it
/// before the first node is created. Every process of one runtime must use the same file.
pub fn use_iceoryx2_config(path: &std::path::Path) -> Result<(), EdgeError> {
    let shown = path.display().to_string();
    let file =
        iceoryx2::prelude::FilePath::new(shown.as_bytes()).map_err(|e| EdgeError::ipc("config path", &shown, e))?;
    Config::setup_global_config_from_file(&file).map_err(|e| EdgeError::ipc("load config", &shown, e))?;
    Ok(())
}

/// Set once SIGINT/SIGTERM was seen: iceoryx2's own flag is cleared by whoever reads it first.
static TERMINATING: AtomicBool = AtomicBool::new(false);

/// Environment variable through which the launcher tells a node its pid: a node whose launcher
/// died (its parent changed) stops, so no orphaned node keeps commanding.
pub const PARENT_ENV: &str = "V2T_LAUNCHER_PID";

fn orphaned() -> bool {
    static LAUNCHER: std::sync::OnceLock<Option<u32>> = std::sync::OnceLock::new();
    let launcher = LAUNCHER.get_or_init(|| std::env::var(PARENT_ENV).ok().and_then(|p| p.parse::<u32>().ok()));
    launcher.is_some_and(|pid| std::os::unix::process::parent_id() != pid)
}

/// Whether SIGINT/SIGTERM arrived, or the launcher that started this node is gone (sticky: stays
/// true once seen).
pub fn terminating() -> bool {
    if TERMINATING.load(Ordering::Relaxed) {
        return true;
    }
    if orphaned() {
        eprintln!("the launcher is gone: stopping");
        TERMINATING.store(true, Ordering::Relaxed);
        return true;
    }
    if iceoryx2_bb_posix::signal::SignalHandler::termination_requested() {
        TERMINATING.store(true, Ordering::Relaxed);
        return true;
    }
    false
}

/// Sends `value` on `publisher`, then wakes `notifier`'s listeners if there is one.
pub fn send<S: Service, T: Debug + ZeroCopySend + Copy + 'static>(
    publisher: &Publisher<S, T, ()>,
    notifier: Option<&Notifier<S>>,
    value: T,
) -> Result<(), EdgeError> {
    publisher.send_copy(value).map_err(|e| EdgeError::ipc("send", &format!("{:?}", publisher.name()), e))?;
    if let Some(n) = notifier {
        n.notify().map_err(|e| EdgeError::ipc("notify", &format!("{:?}", n.name()), e))?;
    }
    Ok(())
}

/// The newest sample waiting on `subscriber`, draining older ones.
pub fn latest<S: Service, T: Debug + ZeroCopySend + Copy + 'static>(
    subscriber: &Subscriber<S, T, ()>,
) -> Result<Option<T>, EdgeError> {
    let mut last = None;
    loop {
        match subscriber.receive() {
            Ok(Some(sample)) => last = Some(*sample),
            Ok(None) => return Ok(last),
            Err(e) => return Err(EdgeError::ipc("receive", &format!("{:?}", subscriber.name()), e)),
        }
    }
}

/// Waits on `listener` up to `timeout` for a wake-up; `Ok(true)` if one came. A wait cut short
/// by SIGINT/SIGTERM returns `Ok(false)`: the caller's `Bus::wait` then sees the termination.
pub fn wait_wake<S: Service>(listener: &Listener<S>, timeout: Duration) -> Result<bool, EdgeError> {
    let mut woke = false;
    match listener.timed_wait(|_| woke = true, timeout) {
        Ok(_) => Ok(woke),
        Err(_) if terminating() => Ok(false),
        Err(e) => Err(EdgeError::ipc("wait", "wake listener", e)),
    }
}

/// Removes what processes that died left behind (their nodes' shared-memory resources), so a
/// restarted node finds free slots. Returns how many dead nodes were cleaned up.
pub fn clean_dead_nodes<S: Service>() -> usize {
    let mut cleaned = 0;
    let _ = Node::<S>::list(Config::global_config(), |state| {
        if let NodeState::Dead(dead) = state
            && dead.try_remove_stale_resources().is_ok()
        {
            cleaned += 1;
        }
        CallbackProgression::Continue
    });
    cleaned
}
