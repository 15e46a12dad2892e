//! `intellwheels bench ...`: benchmarks measured in this run.
//!
//! `bench bus` times a 300-byte FIPA-ACL message between two agents on two buses (an echo peer on
//! its own thread), per transport and per layer set: round-trip latency (p50/p99) one message at a
//! time, then throughput with a window of messages in flight. The `raw` layer set is the peer:
//! the bare transport echoing frames, with no bus, codec or layers. Both ends wait for messages
//! the way agent threads do, in `Mailbox::recv_timeout` / `blocking_recv`. The table also gives
//! throughput per CPU-second of the whole process (all its threads), i.e. per core.

use std::io::Write;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, bail};
use iw_bus::transport::{FrameTransport, PeerAddr};
use iw_bus::{Bus, BusConfig, Clock, InProcNetwork, LayerSet, Mailbox};
use iw_stack::{Platform, StackConfig};
use iw_transport_net::{TcpTransport, UdpTransport};
use iw_transport_shm::ShmTransport;

/// The `bench` subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Message bus round trip and throughput per transport and layer set (300-byte ACL message).
    Bus {
        /// Print one JSON object per line instead of a table.
        #[arg(long)]
        json: bool,
        /// Seconds per row (half for round trips, half for throughput).
        #[arg(long, default_value = "0.6", value_parser = super::flags::seconds)]
        seconds: Duration,
        /// Transports, comma-separated: inproc, iceoryx2, udp, tcp.
        #[arg(long, default_value = "inproc,iceoryx2,udp,tcp")]
        transports: String,
        /// Layer sets to time, each `raw` (bare transport), `none`, `all` or layers joined by `+`
        /// (`comm`, `security`, `temporal`, `parser`, e.g. `security+parser`); repeatable.
        #[arg(long = "layers", default_values_t = ["raw", "none", "comm", "security", "temporal", "parser", "all"].map(String::from))]
        layer_sets: Vec<String>,
        /// Messages in flight during the throughput half.
        #[arg(long, default_value_t = 32, value_parser = super::flags::count(4096))]
        window: usize,
    },
    /// Drive panel input to wheel command: in process (websocket and device queue paths; with
    /// `--browser-dir`, from a real browser's pointer event) and, with `--browser-dir`, across
    /// processes (services serving the dashboard, world, chair).
    Drive {
        /// Print one JSON object per line instead of a table.
        #[arg(long)]
        json: bool,
        /// Inputs timed per path (each takes about 1.2 s; 2.5 s in the browser).
        #[arg(long, default_value_t = 40)]
        trials: usize,
        /// The folder of latency.mjs with playwright-core installed (cli/tests/browser): also
        /// time Chromium's pointer events, in process and across processes (`$CHROMIUM` or
        /// Debian's chromium).
        #[arg(long, value_name = "DIR")]
        browser_dir: Option<std::path::PathBuf>,
    },
    /// The deployment at scale: services, world and N virtual chairs as processes on loopback
    /// UDP; Global Agent List convergence, REQUEST/AGREE round trip, idle CPU per container.
    Fleet {
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
        /// Chair processes to start; a comma list (`10,50,100`) runs each fleet in turn.
        #[arg(long, required = true, value_delimiter = ',', value_parser = super::flags::count(1000))]
        chairs: Vec<usize>,
        /// Seconds the idle CPU is measured over.
        #[arg(long, default_value = "10", value_parser = super::flags::seconds)]
        idle: Duration,
        /// Seconds each run may take before it is abandoned as failed.
        #[arg(long, default_value = "300", value_parser = super::flags::seconds)]
        timeout: Duration,
        /// Heartbeat period between containers, ms (container.heartbeat_ms).
        #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u64).range(1..=10_000))]
        heartbeat_ms: u64,
        /// A container not heard for this long is taken for gone, ms (container.lease_ms).
        #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u64).range(2..=60_000))]
        lease_ms: u64,
        /// Also draw the cost curves against the number of chairs into this PNG.
        #[arg(long, value_name = "PNG")]
        plot: Option<std::path::PathBuf>,
    },
}

pub fn run(command: Command) -> anyhow::Result<ExitCode> {
    match command {
        Command::Bus {
            json,
            seconds,
            transports,
            layer_sets,
            window,
        } => {
            let transports: Vec<Kind> = transports
                .split(',')
                .map(Kind::parse)
                .collect::<anyhow::Result<_>>()?;
            let layer_sets: Vec<Layers> = layer_sets
                .iter()
                .map(|s| Layers::parse(s))
                .collect::<anyhow::Result<_>>()?;
            bench_bus(&transports, &layer_sets, seconds / 2, window, json)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Drive {
            json,
            trials,
            browser_dir,
        } => {
            super::bench_drive::run(trials, json, browser_dir.as_deref())?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Fleet {
            json,
            chairs,
            idle,
            timeout,
            heartbeat_ms,
            lease_ms,
            plot,
        } => {
            let settings = super::bench_fleet::Settings {
                idle,
                timeout,
                heartbeat: Duration::from_millis(heartbeat_ms),
                lease: Duration::from_millis(lease_ms),
            };
            super::bench_fleet::run(&chairs, &settings, json, plot.as_deref())?;
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// One measured row (the JSON line: these keys and no others).
#[derive(Debug, serde::Serialize)]
struct Row {
    transport: &'static str,
    layers: String,
    msgs_per_s: f64,
    rtt_p50_us: f64,
    rtt_p99_us: f64,
    /// Table only.
    #[serde(skip)]
    msgs_per_cpu_s: f64,
}

#[derive(Debug, Clone, Copy)]
enum Kind {
    InProc,
    Iceoryx2,
    Udp,
    Tcp,
}

impl Kind {
    fn parse(s: &str) -> anyhow::Result<Kind> {
        Ok(match s.trim() {
            "inproc" => Kind::InProc,
            "iceoryx2" => Kind::Iceoryx2,
            "udp" => Kind::Udp,
            "tcp" => Kind::Tcp,
            other => bail!("unknown transport `{other}`: expected inproc, iceoryx2, udp or tcp"),
        })
    }

    fn name(self) -> &'static str {
        match self {
            Kind::InProc => "inproc",
            Kind::Iceoryx2 => "iceoryx2",
            Kind::Udp => "udp",
            Kind::Tcp => "tcp",
        }
    }

    /// Two connected endpoints of this transport, named uniquely for this run.
    fn pair(
        self,
        row: usize,
    ) -> anyhow::Result<(Arc<dyn FrameTransport>, Arc<dyn FrameTransport>)> {
        Ok(match self {
            Kind::InProc => {
                let net = InProcNetwork::new();
                (
                    Arc::new(net.endpoint("ping")?),
                    Arc::new(net.endpoint("echo")?),
                )
            }
            Kind::Iceoryx2 => {
                let nanos = SystemTime::now()
                    .duration_since(UNIX_EPOCH)
                    .map(|d| d.as_nanos())
                    .unwrap_or(0);
                let base = format!("bench/{}/{nanos}/{row}", std::process::id());
                (
                    Arc::new(ShmTransport::open(&format!("{base}/ping"))?),
                    Arc::new(ShmTransport::open(&format!("{base}/echo"))?),
                )
            }
            Kind::Udp => (
                Arc::new(UdpTransport::bind("127.0.0.1:0")?),
                Arc::new(UdpTransport::bind("127.0.0.1:0")?),
            ),
            Kind::Tcp => (
                Arc::new(TcpTransport::bind("127.0.0.1:0")?),
                Arc::new(TcpTransport::bind("127.0.0.1:0")?),
            ),
        })
    }
}

enum Layers {
    Raw,
    Bus { name: String, set: LayerSet },
}

impl Layers {
    fn parse(s: &str) -> anyhow::Result<Layers> {
        let s = s.trim();
        if s == "raw" {
            return Ok(Layers::Raw);
        }
        let set = s
            .replace('+', ",")
            .parse::<LayerSet>()
            .with_context(|| format!("layer set `{s}`"))?;
        Ok(Layers::Bus {
            name: s.to_string(),
            set,
        })
    }

    fn name(&self) -> &str {
        match self {
            Layers::Raw => "raw",
            Layers::Bus { name, .. } => name,
        }
    }
}

fn bench_bus(
    kinds: &[Kind],
    layer_sets: &[Layers],
    half: Duration,
    window: usize,
    json: bool,
) -> anyhow::Result<()> {
    let total = (kinds.len() * layer_sets.len()) as u64;
    let progress = indicatif::ProgressBar::new(total).with_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut out = std::io::stdout().lock();
    if !json {
        progress.suspend(|| {
            writeln!(
                out,
                "{:<9} {:<16} {:>12} {:>12} {:>12} {:>12}",
                "transport", "layers", "msgs/s", "msgs/cpu-s", "rtt p50 us", "rtt p99 us"
            )
        })?;
    }
    let mut row_no = 0;
    for &kind in kinds {
        for layers in layer_sets {
            progress.set_message(format!("{} / {}", kind.name(), layers.name()));
            let (a, b) = kind.pair(row_no)?;
            row_no += 1;
            let m = match layers {
                Layers::Raw => measure_raw(a, b, half, window)?,
                Layers::Bus { set, .. } => measure_bus(a, b, set.clone(), half, window)?,
            };
            let row = Row {
                transport: kind.name(),
                layers: layers.name().to_string(),
                msgs_per_s: m.msgs_per_s.round(),
                rtt_p50_us: round1(m.rtt_p50_us),
                rtt_p99_us: round1(m.rtt_p99_us),
                msgs_per_cpu_s: m.msgs_per_cpu_s.round(),
            };
            progress.suspend(|| {
                if json {
                    serde_json::to_writer(&mut out, &row).map_err(anyhow::Error::from)?;
                    writeln!(out)?;
                } else {
                    writeln!(
                        out,
                        "{:<9} {:<16} {:>12.0} {:>12.0} {:>12.1} {:>12.1}",
                        row.transport,
                        row.layers,
                        row.msgs_per_s,
                        row.msgs_per_cpu_s,
                        row.rtt_p50_us,
                        row.rtt_p99_us
                    )?;
                }
                out.flush().map_err(anyhow::Error::from)
            })?;
            progress.inc(1);
        }
    }
    progress.finish_and_clear();
    Ok(())
}

pub(super) fn round1(x: f64) -> f64 {
    (x * 10.0).round() / 10.0
}

struct Measured {
    msgs_per_s: f64,
    /// Messages per second of CPU time of the whole process during the throughput half.
    msgs_per_cpu_s: f64,
    rtt_p50_us: f64,
    rtt_p99_us: f64,
}

/// CPU time used so far by all threads of this process.
fn process_cpu() -> Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; the clock id is a constant the kernel knows.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    Duration::new(
        u64::try_from(ts.tv_sec).unwrap_or(0),
        u32::try_from(ts.tv_nsec).unwrap_or(0),
    )
}

/// The two operations a measurement needs from a ping side, whatever carries the messages.
trait Pinger {
    fn send(&mut self) -> anyhow::Result<()>;
    /// Waits up to `timeout` for one echo.
    fn recv(&mut self, timeout: Duration) -> anyhow::Result<bool>;
}

/// Round trips one at a time for `half`, then a window of `window` in flight for `half`.
fn measure(p: &mut dyn Pinger, half: Duration, window: usize) -> anyhow::Result<Measured> {
    const LOST_AFTER: Duration = Duration::from_millis(200);
    for _ in 0..200 {
        p.send()?;
        p.recv(LOST_AFTER)?;
    }
    let mut rtts_ns = Vec::new();
    let start = Instant::now();
    while start.elapsed() < half {
        let t0 = Instant::now();
        p.send()?;
        if p.recv(LOST_AFTER)? {
            rtts_ns.push(t0.elapsed().as_nanos() as u64);
        }
    }
    if rtts_ns.is_empty() {
        bail!("no echo came back within {LOST_AFTER:?}");
    }
    rtts_ns.sort_unstable();
    let pct = |q: f64| {
        rtts_ns
            .get(((rtts_ns.len() - 1) as f64 * q) as usize)
            .copied()
            .unwrap_or(0) as f64
            / 1e3
    };

    let mut in_flight = 0usize;
    let mut echoed = 0u64;
    let cpu_start = process_cpu();
    let start = Instant::now();
    while start.elapsed() < half {
        while in_flight < window {
            p.send()?;
            in_flight += 1;
        }
        if p.recv(LOST_AFTER)? {
            echoed += 1;
        }
        // A lost message frees its slot too, so a lossy link cannot stall the window.
        in_flight -= 1;
    }
    let elapsed = start.elapsed().as_secs_f64();
    let cpu = process_cpu()
        .saturating_sub(cpu_start)
        .as_secs_f64()
        .max(f64::MIN_POSITIVE);
    while in_flight > 0 && p.recv(LOST_AFTER)? {
        in_flight -= 1;
    }
    // Each echo is two messages delivered: the request and its reply.
    let delivered = 2.0 * echoed as f64;
    Ok(Measured {
        msgs_per_s: delivered / elapsed,
        msgs_per_cpu_s: delivered / cpu,
        rtt_p50_us: pct(0.5),
        rtt_p99_us: pct(0.99),
    })
}

/// A FIPA-ACL request of 300 bytes from `sender` to `receiver`.
fn acl_300(sender: &str, receiver: &str) -> Vec<u8> {
    let head = format!(
        "(request :sender (agent-identifier :name {sender}) :receiver (set (agent-identifier :name {receiver})) \
         :language fipa-sl :ontology wheelchair :conversation-id bench :content \""
    );
    let fill = 300usize.saturating_sub(head.len() + 2);
    let mut text = head;
    text.extend(std::iter::repeat_n('x', fill));
    text.push_str("\")");
    text.into_bytes()
}

struct RawPinger {
    t: Arc<dyn FrameTransport>,
    to: PeerAddr,
    frame: Vec<u8>,
}

impl Pinger for RawPinger {
    fn send(&mut self) -> anyhow::Result<()> {
        Ok(self.t.send(&self.to, &self.frame)?)
    }
    fn recv(&mut self, timeout: Duration) -> anyhow::Result<bool> {
        Ok(self.t.recv_timeout(timeout)?.is_some())
    }
}

fn measure_raw(
    a: Arc<dyn FrameTransport>,
    b: Arc<dyn FrameTransport>,
    half: Duration,
    window: usize,
) -> anyhow::Result<Measured> {
    let stop = Arc::new(AtomicBool::new(false));
    let echo = {
        let (b, stop) = (b.clone(), stop.clone());
        std::thread::spawn(move || -> anyhow::Result<()> {
            while !stop.load(Ordering::Relaxed) {
                if let Some((from, frame)) = b.recv_timeout(Duration::from_millis(20))? {
                    b.send(&from, &frame)?;
                }
            }
            Ok(())
        })
    };
    let mut pinger = RawPinger {
        to: b.local_addr().clone(),
        t: a,
        frame: acl_300("ping", "echo"),
    };
    let result = measure(&mut pinger, half, window);
    stop.store(true, Ordering::Relaxed);
    echo.join()
        .map_err(|_| anyhow::anyhow!("echo thread panicked"))??;
    result
}

struct BusPinger {
    bus: Arc<Bus>,
    mailbox: Mailbox,
    payload: Vec<u8>,
}

impl Pinger for BusPinger {
    fn send(&mut self) -> anyhow::Result<()> {
        self.bus.send("ping", "echo", self.payload.clone())?;
        Ok(())
    }
    fn recv(&mut self, timeout: Duration) -> anyhow::Result<bool> {
        Ok(self.mailbox.recv_timeout(timeout).is_some())
    }
}

fn measure_bus(
    a: Arc<dyn FrameTransport>,
    b: Arc<dyn FrameTransport>,
    set: LayerSet,
    half: Duration,
    window: usize,
) -> anyhow::Result<Measured> {
    let platform = Platform::new();
    let node_a = platform.node(&["ping"])?;
    let node_b = platform.node(&["echo"])?;
    let config = StackConfig::with_layers(set);
    let (addr_a, addr_b) = (a.local_addr().clone(), b.local_addr().clone());
    let bus_a = Arc::new(Bus::start(
        platform.stack(&node_a, &config),
        a,
        Clock::system(),
        BusConfig::default(),
    )?);
    let bus_b = Arc::new(Bus::start(
        platform.stack(&node_b, &config),
        b,
        Clock::system(),
        BusConfig::default(),
    )?);
    bus_a.add_route("echo", addr_b);
    bus_b.add_route("ping", addr_a);
    let mailbox = bus_a.register("ping")?;
    let mut echo_box = bus_b.register("echo")?;
    let echo = {
        let bus_b = bus_b.clone();
        let reply = acl_300("echo", "ping");
        std::thread::spawn(move || -> anyhow::Result<()> {
            // Ends when `echo` is deregistered and its mailbox closes.
            while echo_box.blocking_recv().is_some() {
                bus_b.send("echo", "ping", reply.clone())?;
            }
            Ok(())
        })
    };
    let mut pinger = BusPinger {
        bus: bus_a,
        mailbox,
        payload: acl_300("ping", "echo"),
    };
    let result = measure(&mut pinger, half, window);
    bus_b.deregister("echo");
    echo.join()
        .map_err(|_| anyhow::anyhow!("echo thread panicked"))??;
    result
}
