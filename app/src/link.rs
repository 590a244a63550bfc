//! `video2track keygen`, `serve`, `upload` and `send`: the cloud's side of the link
//! ([`v2t_supervisor`]).

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context as _;
use v2t_files::outln;
use v2t_model::{Style, Target};
use v2t_supervisor::link::{BvEvent, Connection, Signer};
use v2t_supervisor::serve::ServeOptions;
use v2t_wire::link::{ALL_BVS, CloudBody, key_to_hex};

use crate::Usage;

/// Who signs, for which fleet, and how to log in to the broker.
#[derive(Debug, clap::Args)]
pub struct LinkArgs {
    /// Fleet (test session) id: part of every topic.
    #[arg(long, default_value = "demo")]
    fleet: String,
    /// The supervisor's secret key (`video2track keygen`). The default is the committed demo key,
    /// for simulated BVs only.
    #[arg(long, default_value = "config/keys/demo_cloud.key")]
    key: PathBuf,
    /// MQTT user name.
    #[arg(long)]
    username: Option<String>,
    /// Environment variable holding the MQTT password.
    #[arg(long)]
    password_env: Option<String>,
    /// CA certificate (PEM) of an mqtts:// broker.
    #[arg(long)]
    ca_file: Option<PathBuf>,
    /// Client certificate (PEM) for brokers that require one.
    #[arg(long, requires = "client_key")]
    client_cert: Option<PathBuf>,
    /// Its key (PEM).
    #[arg(long, requires = "client_cert")]
    client_key: Option<PathBuf>,
}

impl LinkArgs {
    fn signer(&self) -> anyhow::Result<Signer> {
        let key = v2t_supervisor::link::load_signing_key(&self.key).map_err(crate::BadFile::of)?;
        if v2t_supervisor::link::is_demo_key(&key) {
            eprintln!(
                "warning: signing with the public demo key {}: for simulated BVs only; make your own with `video2track keygen`",
                self.key.display()
            );
        }
        Ok(Signer::new(key, &self.fleet)?)
    }

    fn connection(&self, broker: &str) -> anyhow::Result<Connection> {
        let tls = v2t_supervisor::link::TlsFiles {
            ca: self.ca_file.as_deref(),
            client_cert: self.client_cert.as_deref(),
            client_key: self.client_key.as_deref(),
        };
        Ok(Connection::new(broker, self.username.as_deref(), self.password_env.as_deref(), tls)?)
    }
}

/// One signed frame sent to a broker, waiting for the BV's verdict (`upload`, `send`).
#[derive(Debug, clap::Args)]
pub struct OneShotArgs {
    #[command(flatten)]
    link: LinkArgs,
    /// The broker.
    #[arg(long, default_value = "mqtt://127.0.0.1:1883")]
    broker: String,
    /// Wait this long for the BV's verdict, s (0, or `--bv all`: do not wait).
    #[arg(long, default_value_t = 3.0)]
    wait_s: f64,
}

impl OneShotArgs {
    /// Signs `body` for `bv`, sends it and reports the BV's verdict.
    pub(crate) fn send(&self, bv: &str, body: CloudBody) -> anyhow::Result<()> {
        let mut signer = self.link.signer()?;
        if !(0.0..=600.0).contains(&self.wait_s) {
            return Err(Usage(format!("--wait-s must lie in [0, 600], got {}", self.wait_s)).into());
        }
        let wait = std::time::Duration::from_secs_f64(self.wait_s);
        let conn = self.link.connection(&self.broker)?;
        let answer = v2t_supervisor::link::send_once(&conn, &mut signer, bv, body, wait)?;
        verdict(bv, answer)
    }
}

fn verdict(bv: &str, answer: Option<BvEvent>) -> anyhow::Result<()> {
    match answer {
        Some(e) if e.verdict == "accepted" => {
            outln!("{bv}: accepted {}", e.detail)?;
            Ok(())
        }
        Some(e) => Err(anyhow::anyhow!("{bv} refused it: {}", e.detail)),
        None => {
            outln!("sent")?;
            Ok(())
        }
    }
}

/// `keygen`'s arguments.
#[derive(Debug, clap::Args)]
pub struct KeygenArgs {
    /// Where to write the pair.
    #[arg(long, default_value = "keys")]
    out: PathBuf,
}

/// Makes the key pair and says where it went.
pub fn keygen(a: KeygenArgs) -> anyhow::Result<()> {
    let vk = v2t_supervisor::link::keygen(&a.out)?;
    outln!("wrote {0}/cloud.key (secret, mode 600) and {0}/cloud.pub", a.out.display())?;
    outln!("public key {}: name cloud.pub as `cloud_key` in every BV's [uplink] section", key_to_hex(vk.as_bytes()))?;
    Ok(())
}

/// `serve`'s arguments.
#[derive(Debug, clap::Args)]
pub struct ServeArgs {
    #[command(flatten)]
    link: LinkArgs,
    /// An external broker (mqtt://host:port or mqtts://…) instead of the embedded one.
    #[arg(long)]
    broker: Option<String>,
    /// Address of the embedded broker.
    #[arg(long, default_value = "127.0.0.1:1883")]
    listen: std::net::SocketAddr,
    /// Log every message received as JSON lines here.
    #[arg(long)]
    log: Option<PathBuf>,
    /// Print the fleet table every this many seconds (0: only on `status`).
    #[arg(long, default_value_t = 2.0)]
    status_period_s: f64,
    /// A prior uploaded from the console stays valid this long, s.
    #[arg(long, default_value_t = 600.0)]
    valid_s: f64,
}

/// Runs the supervisor until `quit` or Ctrl-C.
pub fn serve(a: ServeArgs) -> anyhow::Result<()> {
    if !(0.0..=3600.0).contains(&a.status_period_s) {
        return Err(Usage(format!("--status-period-s must lie in [0, 3600], got {}", a.status_period_s)).into());
    }
    let signer = a.link.signer()?;
    let (url, embedded) = match a.broker {
        Some(b) => (b, None),
        None => (format!("mqtt://{}", a.listen), Some(a.listen)),
    };
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst)).context("installing the Ctrl-C handler")?;
    let opts = ServeOptions {
        connection: a.link.connection(&url)?,
        embedded,
        signer,
        log: a.log,
        status_period: std::time::Duration::from_secs_f64(a.status_period_s),
        prior_valid_s: a.valid_s,
    };
    Ok(v2t_supervisor::serve::serve(opts, &stop)?)
}

/// `upload`'s arguments.
#[derive(Debug, clap::Args)]
pub struct UploadArgs {
    /// The priors file.
    priors: PathBuf,
    /// The BV it is for.
    #[arg(long)]
    bv: String,
    /// The prior's BV agent this BV drives (default: the first BV).
    #[arg(long)]
    agent: Option<String>,
    /// Target PET τ, s (default: the file's).
    #[arg(long, value_parser = Target::parse_tau, allow_negative_numbers = true)]
    tau: Option<f64>,
    /// Style, rush or yield (default: the file's).
    #[arg(long)]
    style: Option<Style>,
    /// Identifier the BV reports back (default: from the clock).
    #[arg(long)]
    prior_id: Option<u64>,
    /// Valid for this long from now, s.
    #[arg(long, default_value_t = 600.0)]
    valid_s: f64,
    #[command(flatten)]
    shot: OneShotArgs,
}

/// Signs the prior and sends it.
pub fn upload(a: UploadArgs) -> anyhow::Result<()> {
    let id = a.prior_id.unwrap_or_else(|| (v2t_supervisor::link::unix_ms() % 1_000_000_000).max(1));
    let up = v2t_supervisor::link::prior_from_file(&a.priors, a.agent.as_deref(), (a.tau, a.style), a.valid_s, id)?;
    outln!(
        "prior {id}: {} agents, {:.1} s, τ {} s, {:?}, {} drives {}",
        up.prior.agents.len(),
        up.prior.duration_s(),
        up.prior.target.tau_s(),
        up.prior.target.style(),
        a.bv,
        up.bv_agent
    )?;
    a.shot.send(&a.bv, CloudBody::Prior(up))
}

/// `send`'s arguments.
#[derive(Debug, clap::Args)]
pub struct SendArgs {
    /// What.
    #[arg(value_parser = ["arm", "start", "abort", "target"])]
    action: String,
    /// The BV, or `all`.
    #[arg(long, default_value = "all")]
    bv: String,
    /// New target PET τ, s (target).
    #[arg(long, value_parser = Target::parse_tau, allow_negative_numbers = true)]
    tau: Option<f64>,
    /// New style (target).
    #[arg(long)]
    style: Option<Style>,
    #[command(flatten)]
    shot: OneShotArgs,
}

/// Signs the command and sends it.
pub fn send(a: SendArgs) -> anyhow::Result<()> {
    let cmd = v2t_supervisor::link::command(&a.action, a.tau, a.style)?;
    let bv = if a.bv == "all" { ALL_BVS.to_owned() } else { a.bv };
    a.shot.send(&bv, CloudBody::Command(cmd))
}
