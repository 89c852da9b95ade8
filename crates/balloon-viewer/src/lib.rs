//! Live browser viewer of the balloon simulations (issue 7, `balloon view`).
//!
//! [`Viewer::start`] binds a loopback TCP port, builds the chosen simulation and starts it on a
//! background thread; [`Viewer::serve`] then answers HTTP (the embedded page, `/api/state`) and
//! WebSocket (`/ws`) connections, one thread each, until a deadline. The protocol between the
//! server and the page is in `docs/viewer.md`; [`protocol`] parses and validates what the page
//! sends.
//!
//! * The simulation thread steps in (roughly) real time: it steps while the simulated time is
//!   behind the wall clock since the last (re)start and forgets a lag of more than 0.1 s (a slow
//!   system then runs as fast as it can). It publishes the latest frame at most every 33 ms;
//!   each connection sends the newest frame when its socket has room, so a slow client drops
//!   frames instead of queueing them.
//! * A failing step pauses the simulation and sends an `error` message to every client; the
//!   server keeps running and `reset` rebuilds.
//! * Drags (Song 2009, Sec. 4.4's mouse spring): the shell gets zero-length springs from the
//!   picked vertex's neighbourhood to the target, inside backward Euler's implicit solve
//!   (`ShellSimulation::set_anchor_springs`; a pinch squeezes the neighbourhood towards the
//!   target); the volumetric body a damped spring on the picked surface point, spread to the four
//!   particles that carry it by their barycentric weights and applied as an impulse `h F` in each
//!   step (Diziol, Bender and Bayer 2011, Eq. 1); the two-layer object Song 2009's drag spring on the picked outer
//!   particle.
//! * A panic inside a step or a command is caught and treated like a failing step, and so is a
//!   step that leaves a non-finite position: no frame ever carries one (the last finite frame
//!   stays on the page).
//! * Only the viewer's own page may drive it ([`access`]): every request's `Host` must be a
//!   loopback name (or one given with `--allow-remote`), a browser's `Origin` must be the page
//!   itself, messages and frames over 64 KiB are refused by the transport, at most
//!   [`access::MAX_CONNECTIONS`] connections are served at a time (the next gets a 503), and a
//!   failing `accept` backs off instead of spinning.
//! * Any scenario runs too ([`ViewerOptions::scenario`], `balloon view SCENARIO.toml`, and the
//!   built-in `connect`, [`builtin_connect`]): [`ScenarioView`] builds it with
//!   `balloon-scenario` as `balloon run` does (anchors, pins and scheduled loads included), its
//!   controls edit the scenario's keys, and `/api/scenario` serves the scenario file of the
//!   current set-up, which `balloon run` repeats.
//! * Every failure is a [`ViewerError`].
//!
//! **What it is for:** looking at and playing with one simulation live, from a browser on the
//! same machine; the simulations are driven through `balloon::Simulation`, with each system's
//! controls typed (`ShellControl`, `VolumetricControl`, `TwoLayerControl`) and parsed once from
//! the page's messages. **What it is not for:** file output, recording runs or serving anything
//! beyond loopback (frames, VTK and pictures are the CLI's; the server binds loopback addresses
//! unless told which other names to accept, and has no TLS or authentication).
//!
//! The page's messages are checked before they reach a simulation:
//!
//! ```
//! use balloon_viewer::protocol::{ClientMessage, parse_client_message};
//! let msg = parse_client_message(r#"{"type": "control", "name": "pressure", "value": 1500}"#);
//! assert!(matches!(msg, Ok(ClientMessage::Control { .. })));
//! // Malformed input is an error message for the page, never a panic.
//! assert!(parse_client_message("{not json").is_err());
//! ```

pub mod access;
pub mod protocol;
mod runner;
mod server;
mod systems;

pub use systems::{
    DEFAULT_SHELL_MESH, DEFAULT_VOLUMETRIC_MESH, DragRequest, LYING_ON_ITS_BACK, ScenarioView,
    ShellView, TwoLayerView, ViewSystem, ViewedSimulation, VolumetricView, builtin_connect,
};

use access::{Access, MAX_CONNECTIONS, RefusalLog};
use balloon_mesh::TriMesh;
use runner::{Command, Runner, Shared};
use server::Context;
use std::net::{IpAddr, SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::str::FromStr;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, SyncSender};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use thiserror::Error;

/// Which simulation to view.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SystemKind {
    /// Shell balloon with thickness (Wang et al. 2015).
    Shell,
    /// Volume-conserving lattice body (Diziol, Bender and Bayer 2011).
    Volumetric,
    /// Two-layer elastic sphere (Song 2009).
    TwoLayer,
    /// Shell balloons joined by a tube (`balloon connect`): the viewer's built-in pair,
    /// [`builtin_connect`].
    Connect,
}

impl SystemKind {
    /// The protocol / command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Shell => "shell",
            Self::Volumetric => "volumetric",
            Self::TwoLayer => "two-layer",
            Self::Connect => "connect",
        }
    }
}

impl FromStr for SystemKind {
    type Err = ViewerError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "shell" => Ok(Self::Shell),
            "volumetric" => Ok(Self::Volumetric),
            "two-layer" | "two_layer" | "twolayer" => Ok(Self::TwoLayer),
            "connect" => Ok(Self::Connect),
            _ => Err(ViewerError::UnknownSystem(s.to_string())),
        }
    }
}

/// Errors of the viewer (before serving; later failures are sent to the page).
#[derive(Debug, Error)]
pub enum ViewerError {
    /// Unknown system name.
    #[error("unknown system `{0}` (expected shell, volumetric, two-layer or connect)")]
    UnknownSystem(String),
    /// The port is taken.
    #[error("port {port} on {host} is already in use; pass another --port (or --port 0)")]
    PortInUse {
        /// Host.
        host: String,
        /// Port.
        port: u16,
    },
    /// A non-loopback host without `allow_remote`: bind a loopback address, or name the hosts
    /// clients will use with `--allow-remote`.
    #[error(
        "refusing to listen on {0}: it is not a loopback address, and anyone who can reach it could control the simulation; pass --allow-remote NAME[,NAME...] with the names clients use to reach it to allow it"
    )]
    NotLoopback(String),
    /// A name given with `--allow-remote` is not a host name or address.
    #[error("--allow-remote `{name}`: {reason}")]
    BadAllowedName {
        /// The name as given (control characters replaced, cut).
        name: String,
        /// Why it is refused.
        reason: String,
    },
    /// The host does not resolve.
    #[error("cannot resolve host `{host}`: {reason}")]
    BadHost {
        /// Host.
        host: String,
        /// Why.
        reason: String,
    },
    /// Binding failed for another reason.
    #[error("cannot listen on {host}:{port}: {source}")]
    Bind {
        /// Host.
        host: String,
        /// Port.
        port: u16,
        /// The OS error.
        source: std::io::Error,
    },
    /// The mesh could not be loaded.
    #[error("mesh `{spec}`: {source}")]
    Mesh {
        /// The mesh argument.
        spec: String,
        /// What failed.
        source: balloon_mesh::MeshError,
    },
    /// The simulation could not be built from its default settings (a mesh the system cannot
    /// use, for example an open one for the shell).
    #[error("cannot build the {system} simulation: {source}")]
    Build {
        /// System.
        system: &'static str,
        /// What failed.
        source: Box<ViewerError>,
    },
    /// A scenario that cannot be run: its check or its build failed, or a control's value is
    /// refused by the scenario's own check (the text names the parameter).
    #[error("{0}")]
    Scenario(String),
    /// A scenario run takes its mesh from the scenario.
    #[error("the scenario names its own mesh (`mesh`); drop the MESH argument (got `{0}`)")]
    MeshWithScenario(String),
    /// The two-layer system takes no mesh.
    #[error("the two-layer viewer simulates its own sphere and takes no MESH (got `{0}`)")]
    MeshNotUsed(String),

    // Failures while running (sent to the page as `error` messages, their text unchanged).
    /// A step, a setting or a rebuild of the simulation failed (the system's own error).
    #[error(transparent)]
    Simulation(#[from] balloon::SimulationError),
    /// The two-layer wall box could not be built.
    #[error(transparent)]
    WallBox(#[from] balloon::constraint::ConstraintError),
    /// Young's modulus of the shell control is not a valid material parameter.
    #[error("young: {0}")]
    Young(#[source] balloon::material::MaterialError),
    /// A colour field could not be computed (mismatched lengths, a degenerate rest triangle).
    #[error("scalar field: {0}")]
    Field(#[from] balloon::fields::FieldError),
    /// The floor under the volumetric body could not be placed (a non-finite position).
    #[error("cannot place the floor")]
    Floor,
    /// A control name the system does not have.
    #[error("unknown control `{0}`")]
    UnknownControl(String),
    /// A choice the protocol validated but the system does not know (a control's choice list and
    /// its parser disagree).
    #[error("control `{control}`: unknown choice `{value}`")]
    UnknownChoice {
        /// The control.
        control: String,
        /// The choice.
        value: String,
    },
    /// A validated value of another kind than the control takes.
    #[error("control `{control}`: expected {expected}, got {got}")]
    WrongKind {
        /// The control.
        control: String,
        /// The kind it takes (`a number`, `a choice`, `true or false`).
        expected: &'static str,
        /// The value received.
        got: String,
    },
    /// A colour field the system does not have.
    #[error("unknown scalar field `{0}`")]
    UnknownField(String),
    /// A drag on a vertex the body does not have.
    #[error("vertex {vertex} is out of range")]
    VertexOutOfRange {
        /// The vertex asked for.
        vertex: usize,
    },
    /// A client message the protocol refused (the text names the field and the allowed
    /// values; see [`protocol`]).
    #[error("{0}")]
    Rejected(String),
    /// A drag mode the system does not offer.
    #[error("`drag` message: mode `{mode}` is not available for {system} (use {available})")]
    DragMode {
        /// The mode asked for.
        mode: &'static str,
        /// The system.
        system: &'static str,
        /// The modes it has, comma-separated.
        available: String,
    },
    /// A drag the system could not apply.
    #[error("`drag` message: {0}")]
    Drag(Box<ViewerError>),
    /// Rebuilding after a control that needs it failed (the simulation is paused).
    #[error("control `{control}`: rebuilding failed: {source}")]
    Rebuild {
        /// The control.
        control: String,
        /// What failed.
        source: Box<ViewerError>,
    },
    /// `reset` failed (the simulation is paused).
    #[error("reset failed: {0}")]
    Reset(Box<ViewerError>),
    /// A `scalar` message reached the simulation (each connection chooses its own field).
    #[error("the colour field is chosen by each connection, not the simulation")]
    ScalarNotForSimulation,
    /// A step left a position that is not finite (a blow-up); the simulation is paused and the
    /// last finite frame stays on the page.
    #[error(
        "the state after step {step} has a non-finite position (vertex {vertex}); the last finite frame is shown"
    )]
    NonFinite {
        /// Steps taken, the one that blew up included.
        step: usize,
        /// The first vertex with a non-finite coordinate.
        vertex: usize,
    },
    /// A panic inside a step or a command, caught (the simulation is paused).
    #[error("internal error: {0}")]
    Panic(String),
}

impl From<balloon::shell::ShellError> for ViewerError {
    fn from(e: balloon::shell::ShellError) -> Self {
        Self::Simulation(e.into())
    }
}

impl From<balloon::volumetric::VolumetricError> for ViewerError {
    fn from(e: balloon::volumetric::VolumetricError) -> Self {
        Self::Simulation(e.into())
    }
}

impl From<balloon::two_layer::TwoLayerError> for ViewerError {
    fn from(e: balloon::two_layer::TwoLayerError) -> Self {
        Self::Simulation(e.into())
    }
}

/// Where and what to serve.
#[derive(Clone, Debug)]
pub struct ViewerOptions {
    /// The simulation (ignored when `scenario` is given).
    pub system: SystemKind,
    /// A scenario to run instead of a built-in system (`balloon view SCENARIO.toml`: its
    /// mesh, material, gas, anchors and loads); `None` for the built-in `system`.
    pub scenario: Option<balloon_scenario::Scenario>,
    /// Mesh spec (file or `builtin:NAME`), `None` for the default of the system.
    pub mesh: Option<String>,
    /// Bind address (default `127.0.0.1`).
    pub host: String,
    /// Port (0: the OS picks one).
    pub port: u16,
    /// Extra names accepted in the `Host` and `Origin` headers besides the loopback names and
    /// the bound address (`--allow-remote`); a non-loopback `host` needs at least one.
    pub allow_remote: Vec<String>,
}

impl ViewerOptions {
    /// Options for `system` on `127.0.0.1`, an OS-chosen port, the default mesh.
    pub fn new(system: SystemKind) -> Self {
        Self {
            system,
            scenario: None,
            mesh: None,
            host: "127.0.0.1".into(),
            port: 0,
            allow_remote: Vec::new(),
        }
    }
}

/// The default mesh of a system: a coarse teddy (shell: ~1.2k vertices, fast enough to step
/// interactively; volumetric: the soup of the lattice body).
pub fn default_mesh(system: SystemKind) -> Result<TriMesh, balloon_mesh::MeshError> {
    match system {
        SystemKind::Shell => balloon_mesh::builtin::load(DEFAULT_SHELL_MESH),
        // The coarse teddy lying on its back (face up, +y), at rest on the floor.
        SystemKind::Volumetric => {
            let mut m = balloon_mesh::builtin::load(DEFAULT_VOLUMETRIC_MESH)?;
            // `x -> A x + t` as a scenario's `transform` applies it (exact: products by 0 or 1).
            let t = &LYING_ON_ITS_BACK;
            for p in &mut m.vertices {
                let x = p.coords;
                *p = nalgebra::Point3::new(
                    t[0] * x.x + t[1] * x.y + t[2] * x.z + t[3],
                    t[4] * x.x + t[5] * x.y + t[6] * x.z + t[7],
                    t[8] * x.x + t[9] * x.y + t[10] * x.z + t[11],
                );
            }
            Ok(m)
        }
        SystemKind::TwoLayer => balloon_mesh::generate::icosphere(1.0, 0),
        // One of the built-in pair's balloons (`builtin_connect`).
        SystemKind::Connect => balloon_mesh::builtin::load("builtin:icosphere"),
    }
}

/// Builds the simulation of `options` (no server).
pub fn build_system(options: &ViewerOptions) -> Result<Box<dyn ViewSystem>, ViewerError> {
    let scenario = match (&options.scenario, options.system) {
        (Some(s), _) => Some(s.clone()),
        (None, SystemKind::Connect) => {
            let mut s = builtin_connect();
            if let Some(spec) = &options.mesh {
                s.shell.mesh.path = spec.clone();
            }
            Some(balloon_scenario::Scenario::Connect(s))
        }
        (None, _) => None,
    };
    if let Some(scenario) = scenario {
        if let (Some(spec), Some(_)) = (&options.mesh, &options.scenario) {
            return Err(ViewerError::MeshWithScenario(spec.clone()));
        }
        let name = match scenario.kind() {
            balloon_scenario::SystemKind::Shell => "shell",
            balloon_scenario::SystemKind::Connect => "connect",
            balloon_scenario::SystemKind::Volumetric => "volumetric",
            balloon_scenario::SystemKind::TwoLayer => "two-layer",
        };
        return ScenarioView::new(scenario)
            .map(|s| Box::new(s) as _)
            .map_err(|source| ViewerError::Build {
                system: name,
                source: Box::new(source),
            });
    }
    let mesh = match (&options.mesh, options.system) {
        (Some(spec), SystemKind::TwoLayer) => return Err(ViewerError::MeshNotUsed(spec.clone())),
        (Some(spec), _) => {
            balloon_mesh::builtin::load(spec).map_err(|source| ViewerError::Mesh {
                spec: spec.clone(),
                source,
            })?
        }
        (None, s) => default_mesh(s).map_err(|source| ViewerError::Mesh {
            spec: "default".into(),
            source,
        })?,
    };
    let build = |r: Result<Box<dyn ViewSystem>, ViewerError>| {
        r.map_err(|source| ViewerError::Build {
            system: options.system.name(),
            source: Box::new(source),
        })
    };
    match options.system {
        SystemKind::Shell => build(
            ShellView::new(mesh).map(|s| Box::new(s.with_mesh_spec(options.mesh.clone())) as _),
        ),
        SystemKind::Volumetric => build(
            VolumetricView::new(mesh)
                .map(|s| Box::new(s.with_mesh_spec(options.mesh.clone())) as _),
        ),
        SystemKind::TwoLayer => build(TwoLayerView::new().map(|s| Box::new(s) as _)),
        // Built as a scenario run above; kept for a complete match.
        SystemKind::Connect => build(
            ScenarioView::new(balloon_scenario::Scenario::Connect(builtin_connect()))
                .map(|s| Box::new(s) as _),
        ),
    }
}

/// Checks the host and binds the listener.
pub fn bind(host: &str, port: u16, allow_remote: bool) -> Result<TcpListener, ViewerError> {
    let addrs: Vec<SocketAddr> = match host.parse::<IpAddr>() {
        Ok(ip) => vec![SocketAddr::new(ip, port)],
        Err(_) => (host, port)
            .to_socket_addrs()
            .map_err(|e| ViewerError::BadHost {
                host: host.into(),
                reason: e.to_string(),
            })?
            .collect(),
    };
    if addrs.is_empty() {
        return Err(ViewerError::BadHost {
            host: host.into(),
            reason: "no address".into(),
        });
    }
    if !allow_remote && addrs.iter().any(|a| !a.ip().is_loopback()) {
        return Err(ViewerError::NotLoopback(host.into()));
    }
    TcpListener::bind(&addrs[..]).map_err(|source| {
        if source.kind() == std::io::ErrorKind::AddrInUse {
            ViewerError::PortInUse {
                host: host.into(),
                port,
            }
        } else {
            ViewerError::Bind {
                host: host.into(),
                port,
                source,
            }
        }
    })
}

/// A running viewer: the listener and the simulation thread.
pub struct Viewer {
    listener: TcpListener,
    url: String,
    system: &'static str,
    context: Arc<Context>,
    sim_thread: Option<JoinHandle<()>>,
}

/// Shortest and longest pause of the accept loop after a failed `accept` (out of file
/// descriptors, memory, ...): it doubles after each failure in a row, so a lasting failure
/// costs a few wake-ups per second instead of a busy loop.
const ACCEPT_BACKOFF: (Duration, Duration) = (Duration::from_millis(10), Duration::from_secs(1));

/// Releases a connection's slot when its thread ends (or when the thread could not start).
struct Slot(Arc<AtomicUsize>);

impl Drop for Slot {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

impl Viewer {
    /// Binds, builds the simulation and starts it (the page can connect once
    /// [`Viewer::serve`] runs).
    pub fn start(options: &ViewerOptions) -> Result<Self, ViewerError> {
        let allowed = options
            .allow_remote
            .iter()
            .map(|name| {
                access::allowed_name(name).map_err(|reason| ViewerError::BadAllowedName {
                    name: access::shown(name),
                    reason,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let listener = bind(&options.host, options.port, !allowed.is_empty())?;
        let port = listener
            .local_addr()
            .map_err(|source| ViewerError::Bind {
                host: options.host.clone(),
                port: options.port,
                source,
            })?
            .port();
        let system = build_system(options)?;
        let name = system.name();
        let shared = Arc::new(Shared::default());
        let runner = Runner::new(system, shared.clone());
        let (tx, rx) = mpsc::channel();
        let sim_thread = std::thread::Builder::new()
            .name("balloon-view-sim".into())
            .spawn(move || runner.run(rx))
            .map_err(|source| ViewerError::Bind {
                host: options.host.clone(),
                port,
                source,
            })?;
        let host = if options.host.contains(':') {
            format!("[{}]", options.host)
        } else {
            options.host.clone()
        };
        Ok(Self {
            listener,
            url: format!("http://{host}:{port}/"),
            system: name,
            context: Arc::new(Context {
                shared,
                commands: tx,
                access: Access::new(&options.host, port, &allowed),
                refusals: RefusalLog::default(),
            }),
            sim_thread: Some(sim_thread),
        })
    }

    /// The name of the system served (`shell`, `volumetric`, `two-layer`, `connect`; a scenario
    /// file's system).
    pub fn system(&self) -> &'static str {
        self.system
    }

    /// The page's URL, `http://HOST:PORT/`.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// The names accepted in `Host` and `Origin` headers.
    pub fn accepted_names(&self) -> &[String] {
        self.context.access.names()
    }

    /// Serves connections until `exit_after` has passed (forever with `None`), then stops the
    /// simulation thread.
    ///
    /// At most [`MAX_CONNECTIONS`] are served at a time, each on its own thread; the next ones
    /// are answered 503 by one refusal thread (dropped unanswered when even its queue is
    /// full). A failing `accept` backs off from 10 ms to 1 s and is logged once per run of
    /// failures.
    pub fn serve(mut self, exit_after: Option<Duration>) -> std::io::Result<()> {
        let deadline = exit_after.map(|d| Instant::now() + d);
        self.listener.set_nonblocking(true)?;
        let active = Arc::new(AtomicUsize::new(0));
        let (busy_tx, busy_rx) = mpsc::sync_channel::<TcpStream>(MAX_CONNECTIONS);
        let refuser = {
            let context = self.context.clone();
            std::thread::Builder::new()
                .name("balloon-view-busy".into())
                .spawn(move || {
                    for stream in busy_rx {
                        server::refuse_busy(stream, &context);
                    }
                })?
        };
        let mut backoff: Option<(Duration, u64)> = None;
        while deadline.is_none_or(|d| Instant::now() < d) {
            match self.listener.accept() {
                Ok((stream, _)) => {
                    if let Some((_, failures)) = backoff.take() {
                        eprintln!("balloon view: accepting again after {failures} failed accepts");
                    }
                    self.dispatch(stream, &active, &busy_tx);
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    std::thread::sleep(Duration::from_millis(10));
                }
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionAborted => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    let (pause, failures) = match backoff {
                        None => {
                            eprintln!(
                                "balloon view: accept failed: {e}; retrying with back-off up to {} s (not logged again until an accept succeeds)",
                                ACCEPT_BACKOFF.1.as_secs_f64()
                            );
                            (ACCEPT_BACKOFF.0, 1)
                        }
                        Some((pause, n)) => ((pause * 2).min(ACCEPT_BACKOFF.1), n + 1),
                    };
                    backoff = Some((pause, failures));
                    let left =
                        deadline.map_or(pause, |d| d.saturating_duration_since(Instant::now()));
                    std::thread::sleep(pause.min(left));
                }
            }
        }
        drop(busy_tx);
        let _ = refuser.join();
        if let Some(summary) = self.context.refusals.summary() {
            eprintln!("balloon view: {summary}");
        }
        self.stop();
        Ok(())
    }

    /// Serves `stream` on a thread of its own if a slot is free, else hands it to the refusal
    /// thread.
    fn dispatch(&self, stream: TcpStream, active: &Arc<AtomicUsize>, busy: &SyncSender<TcpStream>) {
        let _ = stream.set_nonblocking(false);
        if active.fetch_add(1, Ordering::SeqCst) >= MAX_CONNECTIONS {
            active.fetch_sub(1, Ordering::SeqCst);
            // A full refusal queue drops the connection unanswered (the error owns it).
            let _ = busy.try_send(stream);
            return;
        }
        let slot = Slot(active.clone());
        let context = self.context.clone();
        let _ = std::thread::Builder::new()
            .name("balloon-view-conn".into())
            .spawn(move || {
                let _slot = slot;
                server::handle_connection(stream, &context);
            });
    }

    fn stop(&mut self) {
        self.context.shared.shutdown.store(true, Ordering::SeqCst);
        let _ = self.context.commands.send(Command::Shutdown);
        if let Some(t) = self.sim_thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        self.stop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn system_names_parse() {
        assert_eq!("shell".parse::<SystemKind>().unwrap(), SystemKind::Shell);
        assert_eq!(
            "Two-Layer".parse::<SystemKind>().unwrap(),
            SystemKind::TwoLayer
        );
        let e = "cloth".parse::<SystemKind>().unwrap_err().to_string();
        assert!(e.contains("unknown system `cloth`"), "{e}");
    }

    #[test]
    fn binding_checks_the_host_and_the_port() {
        let e = bind("0.0.0.0", 0, false).unwrap_err().to_string();
        assert!(
            e.contains("not a loopback") && e.contains("--allow-remote"),
            "{e}"
        );
        let l = bind("127.0.0.1", 0, false).unwrap();
        let port = l.local_addr().unwrap().port();
        let e = bind("127.0.0.1", port, false).unwrap_err().to_string();
        assert_eq!(
            e,
            format!(
                "port {port} on 127.0.0.1 is already in use; pass another --port (or --port 0)"
            )
        );
        assert!(bind("localhost", 0, false).is_ok());
        // Allowed when asked for.
        assert!(bind("0.0.0.0", 0, true).is_ok());
        assert!(matches!(
            bind("no-such-host.invalid", 0, false),
            Err(ViewerError::BadHost { .. })
        ));
    }

    #[test]
    fn allowed_names_are_checked_before_anything_is_bound() {
        let mut o = ViewerOptions::new(SystemKind::TwoLayer);
        o.allow_remote = vec!["ok.lan".into(), "bad\x1b[31m name".into()];
        let e = Viewer::start(&o).err().unwrap();
        assert!(matches!(e, ViewerError::BadAllowedName { .. }), "{e}");
        let text = e.to_string();
        assert!(text.starts_with("--allow-remote `bad?[31m name`"), "{text}");
        // A non-loopback bind needs a name; the names are accepted with the loopback ones.
        o.allow_remote = vec!["MyBox.lan".into()];
        o.host = "127.0.0.1".into();
        let v = Viewer::start(&o).unwrap();
        assert_eq!(
            v.accepted_names(),
            ["127.0.0.1", "[::1]", "localhost", "mybox.lan"]
        );
    }

    /// Sends `request` to `addr` and reads the whole answer: (status, body). A reset
    /// connection fails the test.
    fn ask(addr: &str, request: &[u8]) -> (u16, String) {
        use std::io::{Read, Write};
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        s.write_all(request).unwrap();
        let mut buf = Vec::new();
        s.read_to_end(&mut buf)
            .unwrap_or_else(|e| panic!("no answer but {e}"));
        let text = String::from_utf8_lossy(&buf).to_string();
        let status = text
            .split(' ')
            .nth(1)
            .and_then(|c| c.parse().ok())
            .unwrap_or_else(|| panic!("no status in `{text}`"));
        let body = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
        (status, body.to_string())
    }

    #[test]
    fn oversized_requests_get_an_answer_instead_of_a_reset() {
        let v = Viewer::start(&ViewerOptions::new(SystemKind::TwoLayer)).unwrap();
        let addr = v.url()["http://".len()..].trim_end_matches('/').to_string();
        // Left serving when the test ends (the deadline stops it).
        std::thread::spawn(move || v.serve(Some(Duration::from_secs(60))));
        let long = "a".repeat(20_000);
        let (status, body) = ask(
            &addr,
            format!("GET /?q={long} HTTP/1.1\r\nHost: {addr}\r\n\r\n").as_bytes(),
        );
        assert_eq!(status, 414, "{body}");
        assert!(
            body.contains("request line longer than 16384 bytes"),
            "{body}"
        );
        let (status, body) = ask(
            &addr,
            format!("GET / HTTP/1.1\r\nHost: {addr}\r\nX-Long: {long}\r\n\r\n").as_bytes(),
        );
        assert_eq!(status, 431, "{body}");
        // A huge body is announced and (partly) sent: refused without reading it.
        let mut request = format!(
            "POST /api/state HTTP/1.1\r\nHost: {addr}\r\nContent-Length: 99999999999\r\n\r\n"
        )
        .into_bytes();
        request.extend(std::iter::repeat_n(b'x', 100_000));
        let (status, body) = ask(&addr, &request);
        assert_eq!(status, 413, "{body}");
        assert!(body.contains("a body of 99999999999 bytes"), "{body}");
        let (status, _) = ask(
            &addr,
            format!("GET / HTTP/1.1\r\nHost: {addr}\r\nContent-Length: 123456789012345678901234567890\r\n\r\n").as_bytes(),
        );
        assert_eq!(status, 413);
        let (status, _) = ask(
            &addr,
            format!("GET / HTTP/1.1\r\nHost: {addr}\r\nTransfer-Encoding: chunked\r\n\r\n")
                .as_bytes(),
        );
        assert_eq!(status, 413);
        let (status, body) = ask(
            &addr,
            format!("GET / HTTP/1.1\r\nHost: {addr}\r\nContent-Length: lots\r\n\r\n").as_bytes(),
        );
        assert_eq!(status, 400);
        assert!(body.contains("malformed Content-Length"), "{body}");
        // The server still answers, and saves the built-in two-layer body as a scenario.
        let get = |path: &str| format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\n\r\n");
        assert_eq!(ask(&addr, get("/api/state").as_bytes()).0, 200);
        let (status, body) = ask(&addr, get("/api/scenario").as_bytes());
        assert_eq!(status, 200);
        assert!(body.contains("kind = \"two-layer\""), "{body}");
    }

    #[test]
    fn a_scenario_run_serves_its_scenario() {
        let mut o = ViewerOptions::new(SystemKind::Shell);
        let mut s = balloon_scenario::Scenario::new(balloon_scenario::SystemKind::TwoLayer);
        s.set("level", &balloon_scenario::value::Value::Int(1))
            .unwrap();
        o.scenario = Some(s);
        let v = Viewer::start(&o).unwrap();
        assert_eq!(v.system(), "two-layer");
        let addr = v.url()["http://".len()..].trim_end_matches('/').to_string();
        std::thread::spawn(move || v.serve(Some(Duration::from_secs(60))));
        let (status, body) = ask(
            &addr,
            format!("GET /api/scenario HTTP/1.1\r\nHost: {addr}\r\n\r\n").as_bytes(),
        );
        assert_eq!(status, 200, "{body}");
        assert!(
            body.contains("kind = \"two-layer\"") && body.contains("level = 1"),
            "{body}"
        );
        // A mesh with a scenario is refused (the scenario names its own).
        o.mesh = Some("builtin:box".into());
        let e = build_system(&o).err().unwrap().to_string();
        assert!(e.contains("the scenario names its own mesh"), "{e}");
    }

    /// The next text message of `ws` of type `frame` within `within`, as its frame number.
    fn next_frame(
        ws: &mut tungstenite::WebSocket<tungstenite::stream::MaybeTlsStream<TcpStream>>,
        within: Duration,
    ) -> Option<u64> {
        let end = std::time::Instant::now() + within;
        while std::time::Instant::now() < end {
            match ws.read() {
                Ok(tungstenite::Message::Text(t)) => {
                    let v: serde_json::Value = serde_json::from_str(t.as_str()).unwrap();
                    if v["type"] == "frame" {
                        return v["frame"].as_u64();
                    }
                }
                Ok(_) => {}
                Err(tungstenite::Error::Io(e))
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) => {}
                Err(e) => panic!("{e}"),
            }
        }
        None
    }

    #[test]
    fn a_page_that_acknowledges_frames_is_sent_one_at_a_time() {
        let viewer = Viewer::start(&ViewerOptions::new(SystemKind::TwoLayer)).unwrap();
        let ws_url = format!("{}ws", viewer.url().replace("http://", "ws://"));
        let server = std::thread::spawn(move || viewer.serve(Some(Duration::from_secs(10))));
        let connect = || {
            let (ws, _) = tungstenite::connect(&ws_url).unwrap();
            if let tungstenite::stream::MaybeTlsStream::Plain(s) = ws.get_ref() {
                s.set_read_timeout(Some(Duration::from_millis(20))).unwrap();
            }
            ws
        };
        let (mut paced, mut free) = (connect(), connect());
        let first = next_frame(&mut paced, Duration::from_secs(5)).expect("a first frame");
        let ack = |ws: &mut tungstenite::WebSocket<_>, f: u64| {
            let text = format!(r#"{{"type":"ack","frame":{f}}}"#);
            ws.send(tungstenite::Message::text(text)).unwrap();
        };
        ack(&mut paced, first);
        // Frames already on their way, then the one sent after the ack: then nothing until
        // it is acknowledged (or `ACK_TIMEOUT` passes).
        let mut last = first;
        while let Some(f) = next_frame(&mut paced, Duration::from_millis(300)) {
            last = f;
        }
        assert_eq!(next_frame(&mut paced, Duration::from_millis(500)), None);
        ack(&mut paced, last);
        let next =
            next_frame(&mut paced, Duration::from_millis(500)).expect("a frame after the ack");
        assert!(next > last);
        // A client that never acknowledges gets every frame as before.
        let mut got = 0;
        while got < 5 && next_frame(&mut free, Duration::from_millis(500)).is_some() {
            got += 1;
        }
        assert_eq!(got, 5);
        drop((paced, free));
        // The server stops by itself (`exit_after`); the test does not wait for it.
        drop(server);
    }

    #[test]
    fn two_layer_takes_no_mesh() {
        let mut o = ViewerOptions::new(SystemKind::TwoLayer);
        o.mesh = Some("builtin:box".into());
        assert!(matches!(build_system(&o), Err(ViewerError::MeshNotUsed(_))));
        let mut o = ViewerOptions::new(SystemKind::Shell);
        o.mesh = Some("/no/such/mesh.obj".into());
        let e = build_system(&o).err().unwrap().to_string();
        assert!(e.contains("/no/such/mesh.obj"), "{e}");
    }
}
