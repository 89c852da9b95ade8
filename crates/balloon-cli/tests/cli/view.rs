//! Tests of `balloon view` (issue 7): the real binary on an OS-chosen loopback port, driven over
//! HTTP and a WebSocket as the page would.

use serde_json::{Value, json};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use tungstenite::{Message, WebSocket};

/// A `balloon view` child process; killed when dropped.
struct Server {
    child: Child,
    /// `host:port`.
    addr: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start(args: &[&str]) -> Server {
    let mut command = Command::new(env!("CARGO_BIN_EXE_balloon"));
    command.arg("view").args(args);
    start_command(command, args[0])
}

/// Starts `command` (a `balloon view SYSTEM ...` without the port options) on an OS-chosen port
/// and reads the address from its first line.
fn start_command(mut command: Command, system: &str) -> Server {
    let mut child = command
        .args(["--no-open", "--port", "0", "--exit-after", "60"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start balloon view");
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = BufReader::new(stdout).read_line(&mut line);
        let _ = tx.send(line);
    });
    let line = rx
        .recv_timeout(Duration::from_secs(30))
        .expect("no URL line within 30 s");
    let prefix = format!("balloon view: serving {system} at http://");
    let addr = line
        .trim()
        .strip_prefix(&prefix)
        .and_then(|r| r.strip_suffix('/'))
        .unwrap_or_else(|| panic!("unexpected first line `{line}`"))
        .to_string();
    Server { child, addr }
}

/// GET `path`: (status code, content type, body).
fn get(addr: &str, path: &str) -> (u16, String, Vec<u8>) {
    raw_request(
        addr,
        format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\n\r\n").as_bytes(),
    )
}

fn raw_request(addr: &str, request: &[u8]) -> (u16, String, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    s.write_all(request).unwrap();
    let mut buf = Vec::new();
    s.read_to_end(&mut buf).unwrap();
    let end = buf
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("no head");
    let head = String::from_utf8_lossy(&buf[..end]).to_string();
    let status = head.split(' ').nth(1).unwrap().parse().unwrap();
    let ctype = head
        .lines()
        .find_map(|l| l.strip_prefix("Content-Type: "))
        .unwrap_or("")
        .to_string();
    (status, ctype, buf[end + 4..].to_vec())
}

fn state(addr: &str, query: &str) -> Value {
    let (status, ctype, body) = get(addr, &format!("/api/state{query}"));
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    assert_eq!(ctype, "application/json");
    serde_json::from_slice(&body).unwrap()
}

fn connect(addr: &str) -> WebSocket<TcpStream> {
    let stream = TcpStream::connect(addr).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    let (ws, _) = tungstenite::client(format!("ws://{addr}/ws"), stream).unwrap();
    ws
}

fn send(ws: &mut WebSocket<TcpStream>, v: Value) {
    ws.send(Message::text(v.to_string())).unwrap();
}

/// The next message of `ty` (others are skipped).
fn next_of(ws: &mut WebSocket<TcpStream>, ty: &str) -> Value {
    let deadline = Instant::now() + Duration::from_secs(20);
    while Instant::now() < deadline {
        if let Message::Text(t) = ws.read().unwrap() {
            let v: Value = serde_json::from_str(t.as_str()).unwrap();
            if v["type"] == ty {
                return v;
            }
        }
    }
    panic!("no `{ty}` message within 20 s");
}

fn vertex_position(addr: &str, i: usize) -> [f64; 3] {
    let v = state(addr, &format!("?vertex={i}"));
    let p = &v["vertex"]["position"];
    [0, 1, 2].map(|d| p[d].as_f64().unwrap())
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|d| (a[d] - b[d]).powi(2)).sum::<f64>().sqrt()
}

/// The vertex of a frame farthest from the frame's centroid.
fn farthest_vertex(frame: &Value) -> usize {
    let p = frame_positions(frame);
    let n = p.len() as f64;
    let c = [0, 1, 2].map(|d| p.iter().map(|q| q[d]).sum::<f64>() / n);
    (0..p.len())
        .max_by(|&a, &b| dist(p[a], c).total_cmp(&dist(p[b], c)))
        .unwrap()
}

/// Polls `/api/state` until `ok` holds (10 s at most); returns that state.
fn wait_for(addr: &str, what: &str, ok: impl Fn(&Value) -> bool) -> Value {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let s = state(addr, "");
        if ok(&s) {
            return s;
        }
        assert!(
            Instant::now() < deadline,
            "timed out waiting for {what}: {s}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn frame_positions(frame: &Value) -> Vec<[f64; 3]> {
    let p: Vec<f64> = frame["positions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    p.chunks(3).map(|c| [c[0], c[1], c[2]]).collect()
}

/// A vertex of `frame` about as far from the centroid as `i` whose direction from the centroid
/// is the most nearly perpendicular to `i`'s: a pull on `i` does not carry it outwards, while a
/// uniform swelling or breathing of the body moves both alike.
fn perpendicular_vertex(frame: &Value, i: usize) -> usize {
    let p = frame_positions(frame);
    let n = p.len() as f64;
    let c = [0, 1, 2].map(|d| p.iter().map(|q| q[d]).sum::<f64>() / n);
    let rel = |j: usize| [0, 1, 2].map(|d| p[j][d] - c[d]);
    let ri = dist(p[i], c);
    let cos = |j: usize| {
        let (a, b) = (rel(i), rel(j));
        ((0..3).map(|d| a[d] * b[d]).sum::<f64>() / (ri * dist(p[j], c))).abs()
    };
    (0..p.len())
        .filter(|&j| j != i && dist(p[j], c) >= 0.9 * ri)
        .min_by(|&a, &b| cos(a).total_cmp(&cos(b)))
        .expect("a reference vertex")
}

/// Grabs vertex `i` and pulls it `distance` (m) outwards from the body's centroid; within
/// 2 s of simulation the vertex must close the fraction `min_approach` of its distance to the
/// target and, relative to the centroid, move along the pull by `min_relative` x the bounding-box
/// diagonal beyond what a uniform swelling would give (the body deforms, it is not only
/// carried along or breathing: the swelling is measured on a reference vertex `reference`
/// perpendicular to the pull, chosen from `frame` by [`perpendicular_vertex`]).
fn drag_moves_vertex(
    addr: &str,
    ws: &mut WebSocket<TcpStream>,
    frame: &Value,
    i: usize,
    distance: f64,
    min_approach: f64,
    min_relative: f64,
) {
    let reference = perpendicular_vertex(frame, i);
    send(ws, json!({"type": "pause"}));
    let s = wait_for(addr, "pause", |s| s["paused"] == true);
    let before = vertex_position(addr, i);
    let ref_before = vertex_position(addr, reference);
    let c = [0, 1, 2].map(|d| s["centroid"][d].as_f64().unwrap());
    let diag = dist(
        [0, 1, 2].map(|d| s["bbox_min"][d].as_f64().unwrap()),
        [0, 1, 2].map(|d| s["bbox_max"][d].as_f64().unwrap()),
    );
    let r = dist(before, c);
    let r_ref = dist(ref_before, c);
    let target = [0, 1, 2].map(|d| before[d] + distance * (before[d] - c[d]) / r);
    send(
        ws,
        json!({"type": "drag", "vertex": i, "target": target, "mode": "grab"}),
    );
    send(ws, json!({"type": "resume"}));
    let s = wait_for(addr, "the drag", |s| !s["drag"].is_null());
    assert_eq!(s["drag"]["vertex"], i);
    assert_eq!(s["drag"]["mode"], "grab");
    let t0 = s["time"].as_f64().unwrap();
    let d0 = dist(before, target);
    let mut best = d0;
    let mut relative = f64::NEG_INFINITY;
    let deadline = Instant::now() + Duration::from_secs(15);
    loop {
        let s = state(addr, &format!("?vertex={reference}"));
        assert!(s["last_error"].is_null(), "{s}");
        let p = &s["drag"]["position"];
        let now = [0, 1, 2].map(|d| p[d].as_f64().unwrap());
        best = best.min(dist(now, target));
        let c_now = [0, 1, 2].map(|d| s["centroid"][d].as_f64().unwrap());
        let q = &s["vertex"]["position"];
        let ref_now = [0, 1, 2].map(|d| q[d].as_f64().unwrap());
        let swell = dist(ref_now, c_now) / r_ref;
        // Outward movement relative to the centroid, along the pull, beyond the swelling.
        relative = relative.max(
            (0..3)
                .map(|d| (now[d] - c_now[d]) * (before[d] - c[d]) / r)
                .sum::<f64>()
                - swell * r,
        );
        if (best <= (1.0 - min_approach) * d0 && relative >= min_relative * diag)
            || s["time"].as_f64().unwrap() > t0 + 2.0
        {
            break;
        }
        assert!(Instant::now() < deadline, "simulation too slow: {s}");
        std::thread::sleep(Duration::from_millis(30));
    }
    eprintln!(
        "drag of vertex {i}: distance to the target {d0} -> {best}, outward beyond the swelling \
         {relative} m (diagonal {diag} m)"
    );
    assert!(
        best <= (1.0 - min_approach) * d0,
        "vertex {i}: distance to the target {d0} -> at best {best} (start {before:?}), want a \
         {min_approach} closer"
    );
    assert!(
        relative >= min_relative * diag,
        "vertex {i}: moved {relative} m relative to the centroid beyond the swelling seen on \
         vertex {reference}, want {min_relative} x {diag} m"
    );
    send(ws, json!({"type": "release"}));
    wait_for(addr, "the release", |s| s["drag"].is_null());
}

#[test]
fn view_shell_serves_page_state_frames_controls_and_drags() {
    let srv = start(&["shell"]);
    let (status, ctype, body) = get(&srv.addr, "/");
    assert_eq!(status, 200);
    assert_eq!(ctype, "text/html; charset=utf-8");
    assert!(String::from_utf8_lossy(&body).contains("<html"));
    assert_eq!(get(&srv.addr, "/no-such-file.js").0, 404);
    let s = state(&srv.addr, "");
    assert_eq!(s["system"], "shell");
    let n = s["vertex_count"].as_u64().unwrap() as usize;
    assert!(n > 100);
    assert_eq!(s["controls"]["pressure"], 2000.0);

    let mut ws = connect(&srv.addr);
    let hello = next_of(&mut ws, "hello");
    assert_eq!(hello["system"], "shell");
    assert_eq!(hello["vertex_count"], n);
    assert_eq!(hello["drag_modes"], json!(["grab", "pinch"]));
    let tris = hello["triangles"].as_array().unwrap();
    assert!(tris.len() >= 3 && tris.len().is_multiple_of(3));
    assert!(tris.iter().all(|t| (t.as_u64().unwrap() as usize) < n));
    let names: Vec<&str> = hello["controls"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    for want in [
        "gas",
        "pressure",
        "pump_rate",
        "thickness",
        "material",
        "young",
        "dt",
        "solver",
    ] {
        assert!(names.contains(&want), "{want} missing from {names:?}");
    }

    // Frames with increasing numbers, positions per vertex, a scalar per vertex.
    let mut last = 0;
    for _ in 0..3 {
        let f = next_of(&mut ws, "frame");
        let k = f["frame"].as_u64().unwrap();
        assert!(k > last, "frame {k} after {last}");
        last = k;
        assert_eq!(f["positions"].as_array().unwrap().len(), 3 * n);
        assert_eq!(f["scalar"]["values"].as_array().unwrap().len(), n);
    }

    // A control changes the state.
    send(
        &mut ws,
        json!({"type": "control", "name": "pressure", "value": 3000}),
    );
    wait_for(&srv.addr, "pressure 3000", |s| {
        s["controls"]["pressure"] == 3000.0
    });

    // An invalid value is an error naming the control and its range; the connection lives on.
    send(
        &mut ws,
        json!({"type": "control", "name": "pressure", "value": 1e9}),
    );
    let e = next_of(&mut ws, "error");
    let msg = e["message"].as_str().unwrap();
    assert!(
        msg.contains("`pressure`") && msg.contains("[0, 20000] Pa"),
        "{msg}"
    );
    assert_eq!(state(&srv.addr, "")["controls"]["pressure"], 3000.0);
    send(
        &mut ws,
        json!({"type": "control", "name": "material", "value": "rubber"}),
    );
    let msg = next_of(&mut ws, "error")["message"].to_string();
    assert!(
        msg.contains("`material`") && msg.contains("stvk, neo-hookean"),
        "{msg}"
    );

    // Malformed JSON and unknown messages do not kill anything.
    ws.send(Message::text("{this is not json")).unwrap();
    assert!(
        next_of(&mut ws, "error")["message"]
            .to_string()
            .contains("malformed JSON")
    );
    send(&mut ws, json!({"type": "teleport"}));
    assert!(
        next_of(&mut ws, "error")["message"]
            .to_string()
            .contains("teleport")
    );
    send(
        &mut ws,
        json!({"type": "drag", "vertex": n, "target": [0, 0, 0]}),
    );
    assert!(
        next_of(&mut ws, "error")["message"]
            .to_string()
            .contains("out of range")
    );
    let before = next_of(&mut ws, "frame")["frame"].as_u64().unwrap();
    assert!(next_of(&mut ws, "frame")["frame"].as_u64().unwrap() > before);

    // A scalar field choice reaches this connection's frames, and only this connection's: a
    // second viewer keeps the default field and chooses its own.
    send(&mut ws, json!({"type": "scalar", "name": "stretch"}));
    let deadline = Instant::now() + Duration::from_secs(10);
    while next_of(&mut ws, "frame")["scalar"]["name"] != "stretch" {
        assert!(Instant::now() < deadline, "scalar field not switched");
    }
    let mut other = connect(&srv.addr);
    let default = next_of(&mut other, "hello")["scalar"].clone();
    assert_ne!(default, "stretch");
    assert_eq!(next_of(&mut other, "frame")["scalar"]["name"], default);
    send(&mut other, json!({"type": "scalar", "name": "speed"}));
    while next_of(&mut other, "frame")["scalar"]["name"] != "speed" {
        assert!(
            Instant::now() < deadline,
            "second viewer's field not switched"
        );
    }
    for _ in 0..3 {
        assert_eq!(next_of(&mut ws, "frame")["scalar"]["name"], "stretch");
    }
    send(&mut other, json!({"type": "scalar", "name": "colour"}));
    let msg = next_of(&mut other, "error")["message"].to_string();
    assert!(msg.contains("unknown scalar field `colour`"), "{msg}");
    drop(other);

    // Grab the vertex farthest from the centroid and pull it outwards by 3 cm.
    let f = next_of(&mut ws, "frame");
    let top = farthest_vertex(&f);
    drag_moves_vertex(&srv.addr, &mut ws, &f, top, 0.03, 0.2, 0.01);

    // Pause stops the frame counter of the simulation; reset rebuilds and says hello again.
    send(&mut ws, json!({"type": "pause"}));
    let s1 = wait_for(&srv.addr, "pause", |s| s["paused"] == true);
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(state(&srv.addr, "")["step"], s1["step"]);
    send(&mut ws, json!({"type": "reset"}));
    assert_eq!(next_of(&mut ws, "hello")["system"], "shell");
}

#[test]
fn view_volumetric_streams_the_embedded_surface_and_drags_it() {
    let srv = start(&["volumetric"]);
    let mut ws = connect(&srv.addr);
    let hello = next_of(&mut ws, "hello");
    assert_eq!(hello["system"], "volumetric");
    assert_eq!(hello["drag_modes"], json!(["grab"]));
    let n = hello["vertex_count"].as_u64().unwrap() as usize;
    let f = next_of(&mut ws, "frame");
    assert_eq!(f["positions"].as_array().unwrap().len(), 3 * n);
    // Pinching is a shell-only mode.
    send(
        &mut ws,
        json!({"type": "drag", "vertex": 0, "target": [0, 0, 0], "mode": "pinch"}),
    );
    let msg = next_of(&mut ws, "error")["message"].to_string();
    assert!(msg.contains("pinch") && msg.contains("volumetric"), "{msg}");
    // Gravity is live; without it the drag alone moves the body.
    send(
        &mut ws,
        json!({"type": "control", "name": "gravity", "value": 0.0}),
    );
    send(
        &mut ws,
        json!({"type": "control", "name": "gravity", "value": -1.0}),
    );
    let msg = next_of(&mut ws, "error")["message"].to_string();
    assert!(
        msg.contains("`gravity`") && msg.contains("[0, 30] m/s^2"),
        "{msg}"
    );
    wait_for(&srv.addr, "gravity 0", |s| s["controls"]["gravity"] == 0.0);
    let v = farthest_vertex(&f);
    // The lattice body is moved by an explicit spring capped far below its stability limit
    // (docs/viewer.md): in 2 s the grabbed point closes about 23% of a 3 cm pull. It must also
    // deform the body, not only carry it: measured 4e-4 m (1e-3 of the diagonal) beyond the
    // swelling by the time it closed 10%; half of that is required.
    drag_moves_vertex(&srv.addr, &mut ws, &f, v, 0.03, 0.1, 5e-4);
}

#[test]
fn view_two_layer_drags_the_picked_particle() {
    let srv = start(&["two-layer"]);
    let mut ws = connect(&srv.addr);
    let hello = next_of(&mut ws, "hello");
    assert_eq!(hello["system"], "two-layer");
    let names: Vec<&str> = hello["controls"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["pressure", "integrator", "gravity", "dt", "box"]);
    // The integrator changes live; a wrong one is named.
    send(
        &mut ws,
        json!({"type": "control", "name": "integrator", "value": "symplectic"}),
    );
    send(
        &mut ws,
        json!({"type": "control", "name": "integrator", "value": "leapfrog"}),
    );
    let msg = next_of(&mut ws, "error")["message"].to_string();
    assert!(msg.contains("`integrator`") && msg.contains("rk4"), "{msg}");
    wait_for(&srv.addr, "symplectic", |s| {
        s["controls"]["integrator"] == "symplectic"
    });
    // Gravity off (a reset: a new hello), then pull an outer particle outwards by 0.3 m.
    send(
        &mut ws,
        json!({"type": "control", "name": "gravity", "value": 0.0}),
    );
    let hello = next_of(&mut ws, "hello");
    let n = hello["vertex_count"].as_u64().unwrap() as usize;
    let f = next_of(&mut ws, "frame");
    let v = farthest_vertex(&f);
    assert!(v >= n / 2, "the farthest vertex {v} is an outer particle");
    // The pulled particle moves out relative to the body (measured 0.06 m, 1.6e-2 of the
    // diagonal, when it closed 10% of the pull); a third of that is required.
    drag_moves_vertex(&srv.addr, &mut ws, &f, v, 0.3, 0.1, 5e-3);
}

#[test]
fn view_a_stalled_viewer_blocks_neither_the_simulation_nor_other_viewers() {
    // Viewer `slow` stops reading for 3 s; meanwhile the simulation keeps real time and viewer
    // `fast` keeps getting frames at the usual rate; afterwards `slow` reaches the newest frames
    // (it is sent the latest frame, with whatever was dropped while its socket was full).
    let srv = start(&["two-layer"]);
    let mut slow = connect(&srv.addr);
    let mut fast = connect(&srv.addr);
    next_of(&mut slow, "frame");
    next_of(&mut fast, "frame");
    let t0 = state(&srv.addr, "")["time"].as_f64().unwrap();
    let wall = Instant::now();
    let mut frames = 0;
    while wall.elapsed() < Duration::from_secs(3) {
        next_of(&mut fast, "frame");
        frames += 1;
    }
    let s = state(&srv.addr, "");
    let simulated = s["time"].as_f64().unwrap() - t0;
    // A viewer that blocked the server would stop both at zero. Idle, the simulation keeps real
    // time (3 s) and `fast` gets ~90 frames; the other view tests run their own servers in
    // parallel (shell Newton solves on 2 cores), so the bounds only ask for clear progress.
    eprintln!(
        "stalled viewer: {simulated} s simulated, {frames} frames to the other viewer in 3 s"
    );
    assert!(
        simulated > 0.25,
        "the simulation advanced {simulated} s in 3 s of wall time"
    );
    assert!(frames >= 10, "the other viewer got {frames} frames in 3 s");
    let newest = s["frame"].as_u64().unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let f = next_of(&mut slow, "frame")["frame"].as_u64().unwrap();
        if f >= newest {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the stalled viewer never caught up ({f} < {newest})"
        );
    }
}

#[test]
fn view_rejects_malformed_http_and_survives() {
    let srv = start(&["two-layer"]);
    let (status, _, body) = raw_request(&srv.addr, b"NONSENSE\r\n\r\n");
    assert_eq!(status, 400);
    assert!(String::from_utf8_lossy(&body).contains("malformed request line"));
    let post = format!("POST /api/state HTTP/1.1\r\nHost: {}\r\n\r\n", srv.addr);
    let (status, _, _) = raw_request(&srv.addr, post.as_bytes());
    assert_eq!(status, 405);
    assert_eq!(get(&srv.addr, "/api/state?vertex=99999").0, 400);
    assert_eq!(get(&srv.addr, "/ws").0, 400);
    // A WebSocket client that sends binary and garbage keeps its connection.
    let mut ws = connect(&srv.addr);
    ws.send(Message::binary(vec![1u8, 2, 3])).unwrap();
    assert!(
        next_of(&mut ws, "error")["message"]
            .to_string()
            .contains("binary")
    );
    ws.send(Message::text("[]")).unwrap();
    assert!(
        next_of(&mut ws, "error")["message"]
            .to_string()
            .contains("object")
    );
    let a = next_of(&mut ws, "frame")["frame"].as_u64().unwrap();
    assert!(next_of(&mut ws, "frame")["frame"].as_u64().unwrap() > a);
    assert_eq!(state(&srv.addr, "")["system"], "two-layer");
}

fn run_view(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_balloon"))
        .arg("view")
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn view_port_in_use_and_remote_hosts_are_refused() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port().to_string();
    let out = run_view(&[
        "two-layer",
        "--no-open",
        "--port",
        &port,
        "--exit-after",
        "5",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!(
            "port {port} on 127.0.0.1 is already in use; pass another --port (or --port 0)"
        )),
        "{err}"
    );
    let out = run_view(&[
        "two-layer",
        "--no-open",
        "--host",
        "0.0.0.0",
        "--exit-after",
        "5",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("not a loopback address") && err.contains("--allow-remote"),
        "{err}"
    );
    let out = run_view(&["cloth", "--no-open", "--exit-after", "1"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown system `cloth`"));
}

#[test]
fn view_missing_browser_prints_the_url_and_keeps_serving() {
    let t0 = Instant::now();
    let out = run_view(&[
        "two-layer",
        "--port",
        "0",
        "--browser",
        "/no/such/browser",
        "--exit-after",
        "1.5",
    ]);
    assert!(out.status.success(), "{out:?}");
    assert!(
        t0.elapsed() >= Duration::from_millis(1400),
        "it kept serving"
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.starts_with("balloon view: serving two-layer at http://127.0.0.1:"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("could not open a browser") && err.contains("/no/such/browser"),
        "{err}"
    );
    assert!(err.contains("open http://127.0.0.1:"), "{err}");
}

#[test]
fn view_starts_the_given_browser_with_the_url() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("opened.txt");
    let script = dir.path().join("browser.sh");
    std::fs::write(
        &script,
        format!("#!/bin/sh\necho \"$1\" > {}\n", log.display()),
    )
    .unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let out = run_view(&[
        "two-layer",
        "--browser",
        script.to_str().unwrap(),
        "--exit-after",
        "1",
    ]);
    assert!(out.status.success(), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("could not open"), "{err}");
    let url = String::from_utf8_lossy(&out.stdout)
        .lines()
        .next()
        .unwrap()
        .rsplit(' ')
        .next()
        .unwrap()
        .to_string();
    assert_eq!(std::fs::read_to_string(&log).unwrap().trim(), url);
}

impl Server {
    /// The port the server listens on.
    fn port(&self) -> &str {
        self.addr.rsplit(':').next().unwrap_or("")
    }

    /// Stops the server and returns what it wrote to stderr.
    fn stop(mut self) -> String {
        let mut err = String::new();
        let stderr = self.child.stderr.take();
        let _ = self.child.kill();
        let _ = self.child.wait();
        if let Some(mut e) = stderr {
            let _ = e.read_to_string(&mut err);
        }
        err
    }
}

/// GET `path` with the raw header lines `headers` (no `Host` unless given).
fn get_with(addr: &str, path: &str, headers: &str) -> (u16, String) {
    let (status, _, body) = raw_request(
        addr,
        format!("GET {path} HTTP/1.1\r\n{headers}\r\n").as_bytes(),
    );
    (status, String::from_utf8_lossy(&body).into_owned())
}

/// A WebSocket handshake with the extra headers `headers` (replacing the client's own `Host`
/// when one is given): the socket, or the HTTP status and body of the refusal.
fn handshake(
    addr: &str,
    headers: &[(&'static str, &str)],
) -> Result<WebSocket<TcpStream>, (u16, String)> {
    use tungstenite::client::IntoClientRequest;
    let mut request = format!("ws://{addr}/ws").into_client_request().unwrap();
    for (name, value) in headers {
        request.headers_mut().insert(*name, value.parse().unwrap());
    }
    let stream = TcpStream::connect(addr).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    match tungstenite::client(request, stream) {
        Ok((ws, _)) => Ok(ws),
        Err(tungstenite::HandshakeError::Failure(tungstenite::Error::Http(response))) => {
            let body = response.body().clone().unwrap_or_default();
            Err((
                response.status().as_u16(),
                String::from_utf8_lossy(&body).into_owned(),
            ))
        }
        Err(e) => panic!("handshake failed otherwise: {e}"),
    }
}

#[test]
fn view_refuses_foreign_hosts_and_origins_and_accepts_its_own_page() {
    let srv = start(&["two-layer"]);
    let port = srv.port().to_string();
    // DNS rebinding: a page of evil.example whose name now points at 127.0.0.1.
    let (status, body) = get_with(
        &srv.addr,
        "/api/state",
        &format!("Host: evil.example:{port}\r\n"),
    );
    assert_eq!(status, 403, "{body}");
    assert!(body.contains("Host `evil.example:"), "{body}");
    assert_eq!(get_with(&srv.addr, "/", "Host: evil.example\r\n").0, 403);
    assert_eq!(get_with(&srv.addr, "/api/state", "").0, 403, "no Host");
    for name in ["localhost", "127.0.0.1", "[::1]"] {
        let (status, body) = get_with(&srv.addr, "/api/state", &format!("Host: {name}:{port}\r\n"));
        assert_eq!(status, 200, "{name}: {body}");
    }
    // Cross-site WebSocket hijacking: another page's script opening our socket.
    for origin in [
        "http://evil.example".to_string(),
        format!("http://evil.example:{port}"),
        "http://127.0.0.1:1".to_string(),
        "null".to_string(),
    ] {
        let (status, _) = handshake(&srv.addr, &[("Origin", &origin)])
            .err()
            .unwrap_or_else(|| panic!("Origin {origin} accepted"));
        assert_eq!(status, 403, "{origin}");
    }
    // The reason is one line in the body.
    let (status, body) = get_with(
        &srv.addr,
        "/ws",
        &format!(
            "Host: {}\r\nOrigin: http://evil.example\r\nUpgrade: websocket\r\n",
            srv.addr
        ),
    );
    assert_eq!(status, 403);
    assert!(
        body.contains("Origin `http://evil.example` is not this viewer's page")
            && !body.contains('\n'),
        "{body}"
    );
    let host = format!("evil.example:{port}");
    let origin = format!("http://127.0.0.1:{port}");
    let (status, _) = handshake(&srv.addr, &[("Host", &host), ("Origin", &origin)])
        .expect_err("foreign Host accepted on /ws");
    assert_eq!(status, 403);
    // The page's own origin, under each loopback name, gets the hello.
    for name in ["127.0.0.1", "localhost", "[::1]"] {
        let origin = format!("http://{name}:{port}");
        let host = format!("{name}:{port}");
        let mut ws = handshake(&srv.addr, &[("Host", &host), ("Origin", &origin)])
            .unwrap_or_else(|e| panic!("{origin} refused: {e:?}"));
        assert_eq!(next_of(&mut ws, "hello")["system"], "two-layer");
    }
    // Every refusal was answered; each kind was logged once.
    let err = srv.stop();
    assert_eq!(err.matches("refused: Host").count(), 1, "{err}");
    assert_eq!(err.matches("refused: Origin").count(), 1, "{err}");
}

#[test]
fn view_allow_remote_names_the_extra_hosts() {
    let mut command = Command::new(env!("CARGO_BIN_EXE_balloon"));
    command.args(["view", "two-layer", "--allow-remote", "MyBox.lan,10.1.2.3"]);
    let srv = start_command(command, "two-layer");
    let port = srv.port().to_string();
    for host in ["mybox.lan", "10.1.2.3", "localhost"] {
        let (status, body) = get_with(&srv.addr, "/api/state", &format!("Host: {host}:{port}\r\n"));
        assert_eq!(status, 200, "{host}: {body}");
    }
    assert_eq!(
        get_with(
            &srv.addr,
            "/api/state",
            &format!("Host: other.lan:{port}\r\n")
        )
        .0,
        403
    );
    let host = format!("mybox.lan:{port}");
    let origin = format!("http://mybox.lan:{port}");
    let mut ws = handshake(&srv.addr, &[("Host", &host), ("Origin", &origin)]).unwrap();
    assert_eq!(next_of(&mut ws, "hello")["system"], "two-layer");
    drop(srv);
    // A name with a port or a wildcard is refused before anything is bound.
    for bad in ["host:80", "*"] {
        let out = run_view(&[
            "two-layer",
            "--no-open",
            "--allow-remote",
            bad,
            "--exit-after",
            "1",
        ]);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(&format!("--allow-remote `{bad}`")), "{err}");
    }
}

#[test]
fn view_closes_a_connection_whose_message_is_over_the_limit() {
    const LIMIT: usize = 64 * 1024;
    let srv = start(&["two-layer"]);
    let mut ws = connect(&srv.addr);
    next_of(&mut ws, "hello");
    // At the limit the message reaches the application (and is not JSON).
    ws.send(Message::text("x".repeat(LIMIT))).unwrap();
    assert!(
        next_of(&mut ws, "error")["message"]
            .to_string()
            .contains("malformed JSON")
    );
    // One byte more and the transport refuses it: the connection is closed.
    ws.send(Message::text("x".repeat(LIMIT + 1))).unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    let close = loop {
        match ws.read() {
            Ok(Message::Close(frame)) => break frame,
            Ok(_) => assert!(Instant::now() < deadline, "still open after 10 s"),
            Err(_) => break None,
        }
    };
    if let Some(frame) = close {
        assert_eq!(u16::from(frame.code), 1009, "{frame:?}");
    }
    // A frame header announcing 64 MiB is refused as well, before any payload arrives.
    let mut raw = connect(&srv.addr);
    next_of(&mut raw, "hello");
    let stream = raw.get_mut();
    let mut header = vec![0x81u8, 0xFF];
    header.extend_from_slice(&(64u64 << 20).to_be_bytes());
    header.extend_from_slice(&[1, 2, 3, 4]);
    stream.write_all(&header).unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        match raw.read() {
            Ok(Message::Close(_)) | Err(_) => break,
            Ok(_) => assert!(Instant::now() < deadline, "still open after 10 s"),
        }
    }
    // The server lives on.
    let mut other = connect(&srv.addr);
    assert_eq!(next_of(&mut other, "hello")["system"], "two-layer");
}

#[test]
fn view_answers_503_beyond_sixteen_connections_and_frees_slots() {
    let srv = start(&["two-layer"]);
    let mut sockets: Vec<WebSocket<TcpStream>> = (0..16)
        .map(|_| {
            let mut ws = connect(&srv.addr);
            next_of(&mut ws, "hello");
            ws
        })
        .collect();
    let (status, body) = get_with(&srv.addr, "/api/state", &format!("Host: {}\r\n", srv.addr));
    assert_eq!(status, 503, "{body}");
    assert!(body.contains("at most 16"), "{body}");
    assert_eq!(handshake(&srv.addr, &[]).err().map(|e| e.0), Some(503));
    // A client that leaves frees its slot (and its thread).
    let mut gone = sockets.pop().unwrap();
    let _ = gone.close(None);
    drop(gone);
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let (status, body) = get_with(&srv.addr, "/api/state", &format!("Host: {}\r\n", srv.addr));
        if status == 200 {
            break;
        }
        assert_eq!(status, 503, "{body}");
        assert!(Instant::now() < deadline, "the slot was never freed");
        std::thread::sleep(Duration::from_millis(50));
    }
    drop(sockets);
    let err = srv.stop();
    // Two refusals, logged once.
    assert_eq!(err.matches("too many connections").count(), 1, "{err}");
}

/// CPU time (user + system) of thread `tid` of process `pid`, clock ticks.
#[cfg(target_os = "linux")]
fn thread_ticks(pid: u32, tid: u32) -> u64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/task/{tid}/stat")).unwrap();
    let fields: Vec<&str> = stat[stat.rfind(')').unwrap() + 2..].split(' ').collect();
    fields[11].parse::<u64>().unwrap() + fields[12].parse::<u64>().unwrap()
}

#[cfg(target_os = "linux")]
#[test]
fn view_backs_off_when_out_of_file_descriptors() {
    // 12 descriptors: about 7 connections past stdin/out/err and the listener. Idle clients
    // hold them (each connection waits 5 s for its request head), the next accept fails with
    // EMFILE and must neither spin nor flood the log.
    let mut command = Command::new("sh");
    command.args([
        "-c",
        "ulimit -n 12 && exec \"$0\" \"$@\"",
        env!("CARGO_BIN_EXE_balloon"),
        "view",
        "two-layer",
    ]);
    let srv = start_command(command, "two-layer");
    let pid = srv.child.id();
    let idle: Vec<TcpStream> = (0..20)
        .map(|_| TcpStream::connect(&srv.addr).unwrap())
        .collect();
    std::thread::sleep(Duration::from_millis(800));
    // The accept loop runs on the main thread (its id is the process id).
    let t0 = thread_ticks(pid, pid);
    std::thread::sleep(Duration::from_secs(2));
    let busy = thread_ticks(pid, pid) - t0;
    drop(idle);
    // The held connections time out, the descriptors come back and the server answers again.
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let s = TcpStream::connect(&srv.addr).and_then(|mut s| {
            s.set_read_timeout(Some(Duration::from_secs(10)))?;
            let head = format!("GET /api/state HTTP/1.1\r\nHost: {}\r\n\r\n", srv.addr);
            s.write_all(head.as_bytes())?;
            let mut buf = Vec::new();
            s.read_to_end(&mut buf)?;
            Ok(buf)
        });
        if s.is_ok_and(|b| b.starts_with(b"HTTP/1.1 200")) {
            break;
        }
        assert!(Instant::now() < deadline, "the server never recovered");
        std::thread::sleep(Duration::from_millis(200));
    }
    let err = srv.stop();
    eprintln!("accept loop: {busy} ticks in 2 s while out of descriptors\n{err}");
    let failures = err.matches("accept failed").count();
    assert!(failures >= 1, "no accept failed with EMFILE: {err}");
    assert!(failures <= 5, "{failures} failure lines: {err}");
    assert!(err.contains("accepting again after"), "{err}");
    // A busy loop takes the whole 2 s (about 200 ticks); backing off, a few wake-ups.
    assert!(busy <= 20, "the accept loop used {busy} ticks in 2 s");
}
