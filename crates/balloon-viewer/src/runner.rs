//! The simulation thread: applies client commands, steps in (roughly) real time, publishes the
//! latest frame, hello and state for the connection threads.

use crate::protocol::{ClientMessage, error_message, validate_control, validate_vertex};
use crate::systems::{DragRequest, ViewSystem};
use serde_json::{Map, Value, json};
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
    /// Stop the thread.
    Shutdown,
}

/// What the simulation thread publishes for the connection threads.
#[derive(Default)]
pub struct Published {
    /// The current `hello` message.
    pub hello: Arc<String>,
    /// Bumped whenever `hello` changes (after a reset).
    pub hello_generation: u64,
    /// The latest `frame` message.
    pub frame: Arc<String>,
    /// Frame number of `frame` (strictly increasing over the server's life).
    pub frame_number: u64,
    /// Messages for every client (simulation failures), with increasing sequence numbers.
    pub broadcasts: Vec<(u64, Arc<String>)>,
    /// `/api/state` without the optional vertex.
    pub state: Map<String, Value>,
    /// Positions of the latest frame, flat, m.
    pub positions: Arc<Vec<f64>>,
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
    scalar: &'static str,
    drag: Option<DragRequest>,
    frame_number: u64,
    broadcast_seq: u64,
    anchor: Instant,
    anchor_time: f64,
    last_publish: Option<Instant>,
    dirty: bool,
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
            scalar,
            drag: None,
            frame_number: 0,
            broadcast_seq: 0,
            anchor: Instant::now(),
            anchor_time: time,
            last_publish: None,
            dirty: true,
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
        });
        let mut p = self.shared.lock();
        p.hello = Arc::new(hello.to_string());
        p.hello_generation += 1;
    }

    fn broadcast(&mut self, message: String) {
        self.broadcast_seq += 1;
        let mut p = self.shared.lock();
        p.broadcasts.push((self.broadcast_seq, Arc::new(message)));
        let excess = p.broadcasts.len().saturating_sub(32);
        p.broadcasts.drain(..excess);
    }

    fn fail(&mut self, message: String) {
        self.paused = true;
        self.paused_by_error = true;
        self.last_error = Some(message.clone());
        self.broadcast(error_message(&format!(
            "simulation paused: {message}; press reset to start again"
        )));
        self.dirty = true;
    }

    /// Builds and publishes the frame and the state.
    fn publish_frame(&mut self) {
        let x = self.system.positions();
        let scalar = match self.system.scalar(self.scalar) {
            Ok(values) => {
                let finite = values.iter().copied().filter(|v| v.is_finite());
                let min = finite.clone().fold(f64::INFINITY, f64::min);
                let max = finite.fold(f64::NEG_INFINITY, f64::max);
                let (min, max) = if min <= max { (min, max) } else { (0.0, 0.0) };
                json!({"name": self.scalar, "values": f32s(&values), "min": min, "max": max})
            }
            Err(_) => Value::Null,
        };
        self.frame_number += 1;
        let frame = json!({
            "type": "frame",
            "frame": self.frame_number,
            "step": self.system.steps(),
            "time": self.system.time(),
            "paused": self.paused,
            "positions": f32s(&x),
            "scalar": scalar,
            "stats": self.system.stats(),
        });
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
            "step": self.system.steps(),
            "time": self.system.time(),
            "paused": self.paused,
            "vertex_count": n,
            "centroid": c,
            "bbox_min": lo,
            "bbox_max": hi,
            "controls": controls,
            "scalar": self.scalar,
            "drag": drag,
            "last_error": self.last_error,
            "stats": self.system.stats(),
        });
        let mut p = self.shared.lock();
        p.frame = Arc::new(frame.to_string());
        p.frame_number = self.frame_number;
        p.state = state.as_object().cloned().unwrap_or_default();
        p.positions = Arc::new(x);
        drop(p);
        self.last_publish = Some(Instant::now());
        self.dirty = false;
    }

    fn rebuild(&mut self) -> Result<(), String> {
        self.drag = None;
        self.system.rebuild()?;
        self.last_error = None;
        if self.paused_by_error {
            self.paused = false;
            self.paused_by_error = false;
        }
        self.reanchor();
        self.publish_hello();
        self.dirty = true;
        Ok(())
    }

    /// Applies one client message; `Err` is the text of the error reply.
    pub fn handle(&mut self, message: ClientMessage) -> Result<(), String> {
        self.dirty = true;
        match message {
            ClientMessage::Control { name, value } => {
                let v = validate_control(&self.system.controls(), &name, &value)?;
                if self.system.set_control(&name, &v)? {
                    self.rebuild().map_err(|e| {
                        let msg = format!("control `{name}`: rebuilding failed: {e}");
                        self.fail(msg.clone());
                        msg
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
                let msg = format!("reset failed: {e}");
                self.fail(msg.clone());
                msg
            }),
            ClientMessage::Scalar { name } => {
                let fields = self.system.scalar_fields();
                let f = fields.iter().find(|f| **f == name).ok_or_else(|| {
                    format!(
                        "unknown scalar field `{name}` (this system has: {})",
                        fields.join(", ")
                    )
                })?;
                self.scalar = f;
                Ok(())
            }
            ClientMessage::Drag {
                vertex,
                target,
                mode,
            } => {
                validate_vertex(vertex, self.system.positions().len() / 3)?;
                if !self.system.drag_modes().contains(&mode.name()) {
                    return Err(format!(
                        "`drag` message: mode `{}` is not available for {} (use {})",
                        mode.name(),
                        self.system.name(),
                        self.system.drag_modes().join(", ")
                    ));
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
                        Err(format!("`drag` message: {e}"))
                    }
                }
            }
            ClientMessage::Release => {
                self.drag = None;
                self.system.apply_drag(None)
            }
        }
    }

    /// Runs until a `Shutdown` command, the shared shutdown flag or a closed channel.
    pub fn run(mut self, commands: Receiver<Command>) {
        loop {
            // Apply every pending command first.
            loop {
                match commands.try_recv() {
                    Ok(Command::Shutdown) => return,
                    Ok(Command::Client { message, reply }) => {
                        if let Err(e) = self.handle(message) {
                            let _ = reply.send(error_message(&e));
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
                    let result = self
                        .system
                        .apply_drag(drag.as_ref())
                        .and_then(|()| self.system.step());
                    match result {
                        Ok(()) => self.dirty = true,
                        Err(e) => self.fail(e),
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
                    Ok(Command::Client { message, reply }) => {
                        if let Err(e) = self.handle(message) {
                            let _ = reply.send(error_message(&e));
                        }
                    }
                    Err(RecvTimeoutError::Timeout) => {}
                    Err(RecvTimeoutError::Disconnected) => return,
                }
            }
        }
    }
}
