//! The simulation thread: applies client commands, steps in (roughly) real time, publishes the
//! latest frame, hello and state for the connection threads.

use crate::ViewerError;
use crate::protocol::{
    ClientMessage, error_message, notice_message, validate_control, validate_vertex,
};
use crate::systems::{DragRequest, Sphere, ViewSystem, first_non_finite};
use serde_json::{Map, Value, json};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Shortest wall-clock interval between two published frames (at most ~30 frames/s).
pub const FRAME_INTERVAL: Duration = Duration::from_millis(33);
/// When the simulation falls behind real time by more than this, the lag is forgotten (a slow
/// system runs as fast as it can instead of trying to catch up).
const MAX_LAG: f64 = 0.1;

/// A command for the simulation thread.
pub enum Command {
    /// A parsed client message; errors go back on `reply`.
    Client {
        /// The message.
        message: ClientMessage,
        /// Where the client's error replies go.
        reply: Sender<String>,
    },
    /// Publish a new frame soon even when paused (a connection chose another colour field).
    Refresh,
    /// Stop the thread.
    Shutdown,
}

/// The latest frame: its JSON without the colour field, and the JSON of each field computed
/// for it. Each connection sends it with the field it chose ([`FrameMessage::text`]).
#[derive(Debug, Default)]
pub struct FrameMessage {
    /// The frame object without its closing brace and without `"scalar"`.
    head: String,
    /// The field connections get when they chose none.
    default: &'static str,
    /// `(field, its JSON or null)` for the default field and every field a connection chose.
    scalars: Vec<(&'static str, String)>,
}

impl FrameMessage {
    /// The `frame` message carrying field `scalar`, or the default field when `scalar` is
    /// `None` or was not computed for this frame (chosen after it was built).
    pub fn text(&self, scalar: Option<&str>) -> String {
        let pick = |name: &str| self.scalars.iter().find(|(n, _)| *n == name);
        let field = scalar
            .and_then(pick)
            .or_else(|| pick(self.default))
            .map_or("null", |(_, json)| json.as_str());
        if self.head.is_empty() {
            return String::new();
        }
        format!("{},\"scalar\":{field}}}", self.head)
    }
}

/// What the simulation thread publishes for the connection threads.
#[derive(Default)]
pub struct Published {
    /// The current `hello` message.
    pub hello: Arc<String>,
    /// Bumped whenever `hello` changes (after a reset).
    pub hello_generation: u64,
    /// The latest frame (sent with each connection's colour field).
    pub frame: Arc<FrameMessage>,
    /// Frame number of `frame` (strictly increasing over the server's life).
    pub frame_number: u64,
    /// Messages for every client (simulation failures), with increasing sequence numbers.
    pub broadcasts: Vec<(u64, Arc<String>)>,
    /// `/api/state` without the optional vertex.
    pub state: Map<String, Value>,
    /// Positions of the latest frame, flat, m.
    pub positions: Arc<Vec<f64>>,
    /// The system's colour fields (`scalar_fields`), for the connections to check a choice.
    pub scalar_fields: Vec<&'static str>,
    /// How many connections chose each colour field: the frames carry these and the default.
    pub scalar_interest: BTreeMap<&'static str, usize>,
    /// The scenario file of the current set-up (`/api/scenario`), when the system runs a
    /// scenario ([`ViewSystem::scenario_text`]).
    pub scenario: Option<Arc<String>>,
}

/// State shared by the simulation thread, the accept loop and the connections.
#[derive(Default)]
pub struct Shared {
    /// The published data.
    pub published: Mutex<Published>,
    /// Set when the server stops.
    pub shutdown: AtomicBool,
}

impl Shared {
    /// Locks the published data (a poisoned lock is still usable: the data is replaced whole).
    pub fn lock(&self) -> std::sync::MutexGuard<'_, Published> {
        self.published
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Whether the server is stopping.
    pub fn stopping(&self) -> bool {
        self.shutdown.load(Ordering::SeqCst)
    }
}

/// The simulation thread's state.
pub struct Runner {
    system: Box<dyn ViewSystem>,
    shared: Arc<Shared>,
    paused: bool,
    paused_by_error: bool,
    last_error: Option<String>,
    /// The last notice of the system ([`ViewSystem::take_notice`]), until the next rebuild.
    last_notice: Option<String>,
    /// The colour field of connections that chose none (the system's first).
    scalar: &'static str,
    drag: Option<DragRequest>,
    frame_number: u64,
    broadcast_seq: u64,
    anchor: Instant,
    anchor_time: f64,
    last_publish: Option<Instant>,
    dirty: bool,
    pending_hello: Option<String>,
    /// The last frame whose positions were all finite (sent again, paused, after a blow-up).
    last_finite: Option<FiniteFrame>,
}

/// What a frame shows of a state whose positions are all finite.
#[derive(Clone, Debug)]
struct FiniteFrame {
    positions: Vec<f64>,
    step: usize,
    time: f64,
    stats: Map<String, Value>,
    scalars: Vec<(&'static str, String)>,
    /// The rigid sphere of the scene ([`ViewSystem::sphere`]), finite, or none.
    sphere: Option<Sphere>,
}

/// The error of a caught panic.
fn panic_error(panic: &(dyn std::any::Any + Send)) -> ViewerError {
    let what = panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into());
    ViewerError::Panic(what)
}

fn f32s(v: &[f64]) -> Vec<f32> {
    v.iter().map(|&x| x as f32).collect()
}

impl Runner {
    /// A runner of `system` publishing into `shared` (publishes the first hello and frame).
    pub fn new(system: Box<dyn ViewSystem>, shared: Arc<Shared>) -> Self {
        let scalar = system.scalar_fields().first().copied().unwrap_or("");
        let time = system.time();
        let mut r = Self {
            system,
            shared,
            paused: false,
            paused_by_error: false,
            last_error: None,
            last_notice: None,
            scalar,
            drag: None,
            frame_number: 0,
            broadcast_seq: 0,
            anchor: Instant::now(),
            anchor_time: time,
            last_publish: None,
            dirty: true,
            pending_hello: None,
            last_finite: None,
        };
        r.publish_hello();
        r.publish_frame();
        r
    }

    fn reanchor(&mut self) {
        self.anchor = Instant::now();
        self.anchor_time = self.system.time();
    }

    fn publish_hello(&mut self) {
        let tris: Vec<usize> = self.system.triangles().into_iter().flatten().collect();
        let hello = json!({
            "type": "hello",
            "system": self.system.name(),
            "triangles": tris,
            "vertex_count": self.system.positions().len() / 3,
            "controls": self.system.controls(),
            "scalar_fields": self.system.scalar_fields(),
            "scalar": self.scalar,
            "drag_modes": self.system.drag_modes(),
            "up": self.system.up(),
            "dt": self.system.dt(),
            "scenario": self.system.scenario_text().is_some(),
            "note": self.system.note(),
        });
        // Published together with the next frame (see `publish_frame`), so a client never sees
        // a new hello with an old frame or the reverse.
        self.pending_hello = Some(hello.to_string());
    }

    fn broadcast(&mut self, message: String) {
        self.broadcast_seq += 1;
        let mut p = self.shared.lock();
        p.broadcasts.push((self.broadcast_seq, Arc::new(message)));
        let excess = p.broadcasts.len().saturating_sub(32);
        p.broadcasts.drain(..excess);
    }

    fn fail(&mut self, error: &ViewerError) {
        let message = error.to_string();
        self.paused = true;
        self.paused_by_error = true;
        self.last_error = Some(message.clone());
        self.broadcast(error_message(&format!(
            "simulation paused: {message}; press reset to start again"
        )));
        self.dirty = true;
    }

    /// Builds and publishes the frame and the state. Positions that are not all finite are
    /// never sent: the simulation is paused with the error (once) and the last finite frame is
    /// published again, with the current `paused` flag.
    fn publish_frame(&mut self) {
        let current = self.system.positions();
        let good = match first_non_finite(&current) {
            None => {
                let wanted: Vec<&'static str> = {
                    let p = self.shared.lock();
                    p.scalar_interest
                        .iter()
                        .filter(|(name, n)| **n > 0 && **name != self.scalar)
                        .map(|(name, _)| *name)
                        .collect()
                };
                let scalars: Vec<(&'static str, String)> = std::iter::once(self.scalar)
                    .chain(wanted)
                    .map(|name| (name, self.scalar_json(name)))
                    .collect();
                let good = FiniteFrame {
                    positions: current,
                    step: self.system.steps(),
                    time: self.system.time(),
                    stats: self.system.stats(),
                    scalars,
                    sphere: self
                        .system
                        .sphere()
                        .filter(|s| s.center.iter().chain([&s.radius]).all(|v| v.is_finite())),
                };
                self.last_finite = Some(good.clone());
                good
            }
            Some(vertex) => {
                if !self.paused_by_error {
                    let step = self.system.steps();
                    self.fail(&ViewerError::NonFinite { step, vertex });
                }
                match &self.last_finite {
                    Some(good) => good.clone(),
                    None => {
                        self.dirty = false;
                        return;
                    }
                }
            }
        };
        let x = &good.positions;
        self.frame_number += 1;
        let frame = json!({
            "type": "frame",
            "frame": self.frame_number,
            "step": good.step,
            "time": good.time,
            "paused": self.paused,
            "positions": f32s(x),
            "stats": good.stats,
            "sphere": good.sphere,
        });
        let mut head = frame.to_string();
        head.pop(); // the closing brace: `FrameMessage::text` appends the field and closes it.
        let n = x.len() / 3;
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut c = [0.0; 3];
        for p in x.chunks_exact(3) {
            for d in 0..3 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
                c[d] += p[d] / n.max(1) as f64;
            }
        }
        let controls: Map<String, Value> = self
            .system
            .controls()
            .into_iter()
            .map(|c| (c.name.to_string(), c.value))
            .collect();
        let drag = self.drag.map(|d| {
            let i = d.vertex;
            json!({
                "vertex": i,
                "mode": d.mode.name(),
                "target": d.target,
                "position": [x[3 * i], x[3 * i + 1], x[3 * i + 2]],
            })
        });
        let state = json!({
            "system": self.system.name(),
            "frame": self.frame_number,
            "step": good.step,
            "time": good.time,
            "paused": self.paused,
            "vertex_count": n,
            "centroid": c,
            "bbox_min": lo,
            "bbox_max": hi,
            "controls": controls,
            "scalar": self.scalar,
            "drag": drag,
            "last_error": self.last_error,
            "last_notice": self.last_notice,
            "stats": good.stats,
            "sphere": good.sphere,
        });
        let scenario = self.system.scenario_text().map(Arc::new);
        let mut p = self.shared.lock();
        p.scenario = scenario;
        if let Some(hello) = self.pending_hello.take() {
            p.hello = Arc::new(hello);
            p.hello_generation += 1;
            p.scalar_fields = self.system.scalar_fields();
        }
        p.frame = Arc::new(FrameMessage {
            head,
            default: self.scalar,
            scalars: good.scalars,
        });
        p.frame_number = self.frame_number;
        p.state = state.as_object().cloned().unwrap_or_default();
        p.positions = Arc::new(good.positions);
        drop(p);
        self.last_publish = Some(Instant::now());
        self.dirty = false;
    }

    /// The JSON of colour field `name` for the current state (`null` when it cannot be
    /// computed); min and max over its finite values.
    fn scalar_json(&self, name: &'static str) -> String {
        match self.system.scalar(name) {
            Ok(values) => {
                let finite = values.iter().copied().filter(|v| v.is_finite());
                let min = finite.clone().fold(f64::INFINITY, f64::min);
                let max = finite.fold(f64::NEG_INFINITY, f64::max);
                let (min, max) = if min <= max { (min, max) } else { (0.0, 0.0) };
                json!({"name": name, "values": f32s(&values), "min": min, "max": max}).to_string()
            }
            Err(_) => "null".into(),
        }
    }

    fn rebuild(&mut self) -> Result<(), ViewerError> {
        self.drag = None;
        self.system.rebuild()?;
        // The old simulation's frame may not match the new one's vertices.
        self.last_finite = None;
        self.last_error = None;
        self.last_notice = None;
        if self.paused_by_error {
            self.paused = false;
            self.paused_by_error = false;
        }
        self.reanchor();
        self.publish_hello();
        self.publish_frame();
        Ok(())
    }

    /// Applies one client message; `Err` is the error replied to the client.
    pub fn handle(&mut self, message: ClientMessage) -> Result<(), ViewerError> {
        self.dirty = true;
        match message {
            ClientMessage::Control { name, value } => {
                let v = validate_control(&self.system.controls(), &name, &value)
                    .map_err(ViewerError::Rejected)?;
                if self.system.set_control(&name, &v)? {
                    self.rebuild().map_err(|e| {
                        let e = ViewerError::Rebuild {
                            control: name.clone(),
                            source: Box::new(e),
                        };
                        self.fail(&e);
                        e
                    })?;
                }
                self.reanchor();
                Ok(())
            }
            ClientMessage::Pause => {
                self.paused = true;
                Ok(())
            }
            ClientMessage::Resume => {
                self.paused = false;
                self.paused_by_error = false;
                self.reanchor();
                Ok(())
            }
            ClientMessage::Reset => self.rebuild().map_err(|e| {
                let e = ViewerError::Reset(Box::new(e));
                self.fail(&e);
                e
            }),
            // Each connection chooses its colour field itself (`crate::server`); the choice
            // never reaches the simulation.
            ClientMessage::Scalar { .. } => Err(ViewerError::ScalarNotForSimulation),
            // Acknowledgements pace one connection's frames (`crate::server`); nothing to do.
            ClientMessage::Ack { .. } => Ok(()),
            ClientMessage::Drag {
                vertex,
                target,
                mode,
            } => {
                validate_vertex(vertex, self.system.positions().len() / 3)
                    .map_err(ViewerError::Rejected)?;
                if !self.system.drag_modes().contains(&mode.name()) {
                    return Err(ViewerError::DragMode {
                        mode: mode.name(),
                        system: self.system.name(),
                        available: self.system.drag_modes().join(", "),
                    });
                }
                let req = DragRequest {
                    vertex,
                    target,
                    mode,
                };
                match self.system.apply_drag(Some(&req)) {
                    Ok(()) => {
                        self.drag = Some(req);
                        Ok(())
                    }
                    Err(e) => {
                        self.drag = None;
                        let _ = self.system.apply_drag(None);
                        Err(ViewerError::Drag(Box::new(e)))
                    }
                }
            }
            ClientMessage::Release => {
                self.drag = None;
                self.system.apply_drag(None)
            }
        }
    }

    /// [`Runner::handle`], with a panic turned into a failure (pause, `last_error`).
    fn handle_safely(&mut self, message: ClientMessage) -> Result<(), ViewerError> {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| self.handle(message)))
            .unwrap_or_else(|panic| {
                let e = panic_error(panic.as_ref());
                self.fail(&e);
                Err(e)
            })
    }

    /// Runs until a `Shutdown` command, the shared shutdown flag or a closed channel.
    pub fn run(mut self, commands: Receiver<Command>) {
        loop {
            // Apply every pending command first.
            loop {
                match commands.try_recv() {
                    Ok(Command::Shutdown) => return,
                    Ok(Command::Refresh) => self.dirty = true,
                    Ok(Command::Client { message, reply }) => {
                        if let Err(e) = self.handle_safely(message) {
                            let _ = reply.send(error_message(&e.to_string()));
                        }
                    }
                    Err(std::sync::mpsc::TryRecvError::Empty) => break,
                    Err(std::sync::mpsc::TryRecvError::Disconnected) => return,
                }
            }
            if self.shared.stopping() {
                return;
            }
            let mut wait = None;
            if self.paused {
                wait = Some(FRAME_INTERVAL);
            } else {
                let wall = self.anchor.elapsed().as_secs_f64();
                let sim = self.system.time() - self.anchor_time;
                if sim > wall {
                    wait = Some(Duration::from_secs_f64((sim - wall).min(0.01)));
                } else {
                    if wall - sim > MAX_LAG {
                        self.reanchor();
                    }
                    let drag = self.drag;
                    let system = &mut self.system;
                    // A panic inside a solver must not end the thread: it becomes a failure
                    // (the state may be inconsistent, so only a reset goes on).
                    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                        system
                            .apply_drag(drag.as_ref())
                            .and_then(|()| system.step())
                    }))
                    .unwrap_or_else(|panic| Err(panic_error(panic.as_ref())));
                    match result {
                        // A blow-up is caught at the step that made it, before any frame.
                        Ok(()) => match self.system.simulation().first_non_finite() {
                            None => {
                                self.dirty = true;
                                if let Some(notice) = self.system.take_notice() {
                                    // The system undid the drag: a new one begins with the
                                    // page's next drag message.
                                    self.drag = None;
                                    self.broadcast(notice_message(&notice));
                                    self.last_notice = Some(notice);
                                }
                            }
                            Some(vertex) => {
                                let step = self.system.steps();
                                self.fail(&ViewerError::NonFinite { step, vertex });
                            }
                        },
                        Err(e) => self.fail(&e),
                    }
                }
            }
            let due = self
                .last_publish
                .is_none_or(|t| t.elapsed() >= FRAME_INTERVAL);
            if self.dirty && due {
                self.publish_frame();
            }
            if let Some(w) = wait {
                match commands.recv_timeout(w) {
                    Ok(Command::Shutdown) => return,
                    Ok(Command::Refresh) => self.dirty = true,
                    Ok(Command::Client { message, reply }) => {
                        if let Err(e) = self.handle_safely(message) {
                            let _ = reply.send(error_message(&e.to_string()));
                        }
                    }
                    Err(RecvTimeoutError::Timeout) => {}
                    Err(RecvTimeoutError::Disconnected) => return,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{ControlSpec, ControlValue, DragMode};
    use crate::systems::ViewedSimulation;
    use serde_json::json;

    /// A test double: a point that moves at 1 m/s along x, fails on the step given by `fail_at`
    /// until rebuilt, and has one control of each kind.
    struct Toy {
        x: f64,
        steps: usize,
        fail_at: Option<usize>,
        speed: f64,
        rebuilds: usize,
        drag: Option<DragRequest>,
        /// From this step on the positions are NaN (a blow-up that does not fail the step).
        nan_from: Option<usize>,
        /// After this step the toy undoes its drag and says so once (`take_notice`).
        notice_at: Option<usize>,
    }

    impl Toy {
        fn new(fail_at: Option<usize>) -> Self {
            Self {
                x: 0.0,
                steps: 0,
                fail_at,
                speed: 1.0,
                rebuilds: 0,
                drag: None,
                nan_from: None,
                notice_at: None,
            }
        }
    }

    impl ViewSystem for Toy {
        fn name(&self) -> &'static str {
            "toy"
        }
        fn controls(&self) -> Vec<ControlSpec> {
            vec![
                ControlSpec::number("speed", "Speed", self.speed, (0.0, 10.0, 0.1), "m/s", false),
                ControlSpec::choice("shape", "Shape", "a", &["a", "b"], true),
            ]
        }
        fn set_control(&mut self, name: &str, value: &ControlValue) -> Result<bool, ViewerError> {
            match name {
                "speed" => {
                    self.speed = value.number();
                    Ok(false)
                }
                _ => Ok(true),
            }
        }
        fn rebuild(&mut self) -> Result<(), ViewerError> {
            self.x = 0.0;
            self.steps = 0;
            self.fail_at = None;
            self.nan_from = None;
            self.rebuilds += 1;
            Ok(())
        }
        fn simulation(&self) -> &dyn ViewedSimulation {
            self
        }
        fn simulation_mut(&mut self) -> &mut dyn ViewedSimulation {
            self
        }
        fn stats(&self) -> Map<String, Value> {
            Map::new()
        }
        fn scalar_fields(&self) -> Vec<&'static str> {
            vec!["x", "y"]
        }
        fn scalar(&self, name: &str) -> Result<Vec<f64>, ViewerError> {
            match name {
                "x" => Ok(vec![self.x, self.x + 1.0, self.x]),
                _ => Ok(vec![0.0, 0.0, 1.0]),
            }
        }
        fn drag_modes(&self) -> Vec<&'static str> {
            vec!["grab"]
        }
        fn apply_drag(&mut self, drag: Option<&DragRequest>) -> Result<(), ViewerError> {
            self.drag = drag.copied();
            Ok(())
        }
        fn take_notice(&mut self) -> Option<String> {
            (self.notice_at == Some(self.steps) && self.drag.is_some())
                .then(|| format!("toy undid the drag at step {}", self.steps))
        }
    }

    impl ViewedSimulation for Toy {
        fn triangles(&self) -> Vec<[usize; 3]> {
            vec![[0, 1, 2]]
        }
        fn positions(&self) -> Vec<f64> {
            let x = if self.nan_from.is_some_and(|k| self.steps >= k) {
                f64::NAN
            } else {
                self.x
            };
            vec![x, 0.0, 0.0, x + 1.0, 0.0, 0.0, x, 1.0, 0.0]
        }
        fn time(&self) -> f64 {
            self.steps as f64 * ViewedSimulation::dt(self)
        }
        fn steps(&self) -> usize {
            self.steps
        }
        fn dt(&self) -> f64 {
            0.01
        }
        fn step(&mut self) -> Result<(), ViewerError> {
            if self.speed == 9.0 {
                panic!("toy panic");
            }
            if self.fail_at == Some(self.steps) {
                return Err(ViewerError::Rejected(format!(
                    "toy failure at step {}",
                    self.steps
                )));
            }
            self.x += self.speed * ViewedSimulation::dt(self);
            self.steps += 1;
            Ok(())
        }
    }

    fn runner(fail_at: Option<usize>) -> (Runner, Arc<Shared>) {
        let shared = Arc::new(Shared::default());
        (
            Runner::new(Box::new(Toy::new(fail_at)), shared.clone()),
            shared,
        )
    }

    #[test]
    fn hello_frame_and_state_are_published_at_start() {
        let (_r, shared) = runner(None);
        let p = shared.lock();
        let hello: Value = serde_json::from_str(&p.hello).unwrap();
        assert_eq!(hello["type"], "hello");
        assert_eq!(hello["triangles"], json!([0, 1, 2]));
        assert_eq!(hello["vertex_count"], 3);
        assert_eq!(hello["scalar"], "x");
        let frame: Value = serde_json::from_str(&p.frame.text(None)).unwrap();
        assert_eq!(frame["frame"], 1);
        assert_eq!(frame["scalar"]["name"], "x");
        assert_eq!(frame["positions"].as_array().unwrap().len(), 9);
        assert_eq!(frame["scalar"]["min"], 0.0);
        assert_eq!(frame["scalar"]["max"], 1.0);
        assert_eq!(p.state["controls"]["speed"], 1.0);
        assert_eq!(p.hello_generation, 1);
    }

    #[test]
    fn frames_carry_the_default_field_and_every_field_a_connection_chose() {
        let (mut r, shared) = runner(None);
        let frame = |choice: Option<&str>| -> Value {
            serde_json::from_str(&shared.lock().frame.text(choice)).unwrap()
        };
        // Only the default is computed at first: a choice not computed yet falls back to it.
        assert_eq!(frame(Some("y"))["scalar"]["name"], "x");
        shared.lock().scalar_interest.insert("y", 1);
        r.publish_frame();
        assert_eq!(frame(Some("y"))["scalar"]["name"], "y");
        assert_eq!(frame(None)["scalar"]["name"], "x");
        assert_eq!(frame(Some("x"))["scalar"]["name"], "x");
        assert_eq!(shared.lock().frame.scalars.len(), 2);
        // Nobody wants `y` any more: it is no longer computed.
        shared.lock().scalar_interest.clear();
        r.publish_frame();
        assert_eq!(shared.lock().frame.scalars.len(), 1);
    }

    #[test]
    fn every_rejection_names_what_is_wrong() {
        let (mut r, _) = runner(None);
        let c = |name: &str, value: Value| ClientMessage::Control {
            name: name.into(),
            value,
        };
        let e = r.handle(c("speed", json!(11))).unwrap_err().to_string();
        assert!(e.contains("`speed`") && e.contains("[0, 10] m/s"), "{e}");
        let e = r.handle(c("colour", json!(1))).unwrap_err().to_string();
        assert!(e.contains("unknown control `colour`"), "{e}");
        // The colour field is chosen per connection (server tests), never by the simulation.
        let e = r
            .handle(ClientMessage::Scalar { name: "y".into() })
            .unwrap_err()
            .to_string();
        assert!(e.contains("each connection"), "{e}");
        let drag = |vertex, mode| ClientMessage::Drag {
            vertex,
            target: [0.0; 3],
            mode,
        };
        let e = r.handle(drag(3, DragMode::Grab)).unwrap_err().to_string();
        assert!(e.contains("vertex 3 is out of range"), "{e}");
        let e = r.handle(drag(0, DragMode::Pinch)).unwrap_err().to_string();
        assert!(e.contains("pinch") && e.contains("toy"), "{e}");
        assert!(r.drag.is_none());
        // Valid ones pass.
        r.handle(c("speed", json!(2.5))).unwrap();
        r.handle(drag(2, DragMode::Grab)).unwrap();
        assert_eq!(r.drag.map(|d| d.vertex), Some(2));
        r.handle(ClientMessage::Release).unwrap();
        assert!(r.drag.is_none());
    }

    #[test]
    fn a_failing_step_pauses_and_reset_recovers() {
        let (r, shared) = runner(Some(3));
        let (tx, rx) = std::sync::mpsc::channel();
        let (reply, _replies) = std::sync::mpsc::channel();
        let thread = std::thread::spawn(move || {
            r.run(rx);
        });
        let wait = |what: &str, ok: &dyn Fn(&Published) -> bool| {
            let deadline = Instant::now() + Duration::from_secs(10);
            while !ok(&shared.lock()) {
                assert!(Instant::now() < deadline, "timed out waiting for {what}");
                std::thread::sleep(Duration::from_millis(5));
            }
        };
        wait("the failure", &|p| p.state["paused"] == true);
        {
            let p = shared.lock();
            assert_eq!(p.state["step"], 3);
            let e = p.state["last_error"].as_str().unwrap();
            assert!(e.contains("toy failure at step 3"), "{e}");
            let b: Value = serde_json::from_str(&p.broadcasts.last().unwrap().1).unwrap();
            assert_eq!(b["type"], "error");
            assert!(b["message"].as_str().unwrap().contains("press reset"));
        }
        tx.send(Command::Client {
            message: ClientMessage::Reset,
            reply: reply.clone(),
        })
        .unwrap();
        wait("the rebuild", &|p| p.hello_generation == 2);
        wait("stepping again", &|p| {
            p.state["paused"] == false && p.state["step"].as_u64() > Some(5)
        });
        assert!(shared.lock().state["last_error"].is_null());
        // Pause stops the steps; frames keep increasing numbers.
        tx.send(Command::Client {
            message: ClientMessage::Pause,
            reply,
        })
        .unwrap();
        wait("the pause", &|p| p.state["paused"] == true);
        let (step, frame) = {
            let p = shared.lock();
            (p.state["step"].clone(), p.frame_number)
        };
        std::thread::sleep(Duration::from_millis(100));
        assert_eq!(shared.lock().state["step"], step);
        assert!(frame > 1);
        tx.send(Command::Shutdown).unwrap();
        thread.join().unwrap();
    }

    /// A step after which the system undid the drag (`take_notice`): the runner drops its
    /// drag, keeps stepping, broadcasts the notice and shows it in the state.
    #[test]
    fn a_notice_drops_the_drag_and_reaches_the_page() {
        let shared = Arc::new(Shared::default());
        let mut toy = Toy::new(None);
        toy.notice_at = Some(4);
        let mut r = Runner::new(Box::new(toy), shared.clone());
        r.handle(ClientMessage::Drag {
            vertex: 1,
            target: [0.0; 3],
            mode: DragMode::Grab,
        })
        .unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        let thread = std::thread::spawn(move || r.run(rx));
        let deadline = Instant::now() + Duration::from_secs(10);
        while shared.lock().state["step"].as_u64() < Some(8) {
            assert!(Instant::now() < deadline, "timed out waiting for step 8");
            std::thread::sleep(Duration::from_millis(5));
        }
        tx.send(Command::Shutdown).unwrap();
        thread.join().unwrap();
        let p = shared.lock();
        assert_eq!(p.state["paused"], false);
        assert!(p.state["last_error"].is_null());
        assert!(p.state["drag"].is_null(), "{}", p.state["drag"]);
        assert_eq!(p.state["last_notice"], "toy undid the drag at step 4");
        let notices: Vec<Value> = p
            .broadcasts
            .iter()
            .map(|(_, b)| serde_json::from_str::<Value>(b).unwrap())
            .filter(|b| b["type"] == "notice")
            .collect();
        assert_eq!(notices.len(), 1, "{notices:?}");
        assert_eq!(notices[0]["message"], "toy undid the drag at step 4");
    }

    #[test]
    fn non_finite_positions_are_found_by_vertex() {
        assert_eq!(first_non_finite(&[0.0, 1.0, 2.0, 3.0, 4.0, 5.0]), None);
        assert_eq!(
            first_non_finite(&[0.0, 1.0, 2.0, 3.0, f64::NAN, 5.0]),
            Some(1)
        );
        assert_eq!(first_non_finite(&[f64::INFINITY, 0.0, 0.0]), Some(0));
        assert_eq!(first_non_finite(&[]), None);
    }

    #[test]
    fn a_blow_up_pauses_and_no_frame_carries_a_non_finite_position() {
        let shared = Arc::new(Shared::default());
        let mut toy = Toy::new(None);
        toy.nan_from = Some(4);
        let r = Runner::new(Box::new(toy), shared.clone());
        let (tx, rx) = std::sync::mpsc::channel();
        let (reply, _replies) = std::sync::mpsc::channel();
        let thread = std::thread::spawn(move || r.run(rx));
        // Watch every published frame until the pause.
        let deadline = Instant::now() + Duration::from_secs(10);
        let mut frames = Vec::new();
        loop {
            let (text, paused) = {
                let p = shared.lock();
                (p.frame.text(None), p.state["paused"] == true)
            };
            frames.push(text);
            if paused {
                break;
            }
            assert!(Instant::now() < deadline, "no pause after the blow-up");
            std::thread::sleep(Duration::from_millis(2));
        }
        // A control while paused publishes again: still the last finite frame.
        tx.send(Command::Client {
            message: ClientMessage::Control {
                name: "speed".into(),
                value: json!(2.0),
            },
            reply,
        })
        .unwrap();
        std::thread::sleep(Duration::from_millis(100));
        frames.push(shared.lock().frame.text(None));
        for text in &frames {
            let f: Value = serde_json::from_str(text).unwrap();
            let positions = f["positions"].as_array().unwrap();
            assert!(positions.iter().all(Value::is_f64), "{text}");
            assert!(f["step"].as_u64().unwrap() < 4, "{text}");
        }
        let last: Value = serde_json::from_str(frames.last().unwrap()).unwrap();
        assert_eq!(last["paused"], true);
        let p = shared.lock();
        assert!(p.positions.iter().all(|v| v.is_finite()));
        assert!(p.state["centroid"][0].is_f64(), "{:?}", p.state);
        let e = p.state["last_error"].as_str().unwrap();
        assert!(
            e.contains("after step 4") && e.contains("non-finite position (vertex 0)"),
            "{e}"
        );
        // Reported once, not at every publish.
        let reports = p
            .broadcasts
            .iter()
            .filter(|(_, b)| b.contains("non-finite"))
            .count();
        assert_eq!(reports, 1);
        drop(p);
        tx.send(Command::Shutdown).unwrap();
        thread.join().unwrap();
    }

    #[test]
    fn stepping_follows_the_wall_clock() {
        let (r, shared) = runner(None);
        let (tx, rx) = std::sync::mpsc::channel();
        let t0 = Instant::now();
        let thread = std::thread::spawn(move || r.run(rx));
        std::thread::sleep(Duration::from_millis(500));
        let time = shared.lock().state["time"].as_f64().unwrap();
        let wall = t0.elapsed().as_secs_f64();
        tx.send(Command::Shutdown).unwrap();
        thread.join().unwrap();
        // The toy steps in no time: real time holds it back (one publish interval of slack).
        assert!(time <= wall + 0.05, "sim {time} s after {wall} s");
        assert!(time >= 0.5 * wall - 0.05, "sim {time} s after {wall} s");
    }

    #[test]
    fn a_panicking_step_pauses_instead_of_killing_the_thread() {
        let (r, shared) = runner(None);
        let (tx, rx) = std::sync::mpsc::channel();
        let (reply, _replies) = std::sync::mpsc::channel();
        let thread = std::thread::spawn(move || r.run(rx));
        tx.send(Command::Client {
            message: ClientMessage::Control {
                name: "speed".into(),
                value: json!(9.0),
            },
            reply: reply.clone(),
        })
        .unwrap();
        let deadline = Instant::now() + Duration::from_secs(10);
        while shared.lock().state["paused"] != true {
            assert!(Instant::now() < deadline, "no pause after the panic");
            std::thread::sleep(Duration::from_millis(5));
        }
        let e = shared.lock().state["last_error"]
            .as_str()
            .unwrap()
            .to_string();
        assert!(
            e.contains("internal error") && e.contains("toy panic"),
            "{e}"
        );
        // The thread still answers.
        tx.send(Command::Client {
            message: ClientMessage::Control {
                name: "speed".into(),
                value: json!(1.0),
            },
            reply,
        })
        .unwrap();
        while shared.lock().state["controls"]["speed"] != 1.0 {
            assert!(Instant::now() < deadline, "the thread no longer answers");
            std::thread::sleep(Duration::from_millis(5));
        }
        tx.send(Command::Shutdown).unwrap();
        thread.join().unwrap();
    }
}
