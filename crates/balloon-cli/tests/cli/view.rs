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
    let mut child = Command::new(env!("CARGO_BIN_EXE_balloon"))
        .arg("view")
        .args(args)
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
    let prefix = format!("balloon view: serving {} at http://", args[0]);
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
    // (docs/viewer.md): in 2 s the grabbed point closes about 23% of a 3 cm pull.
    drag_moves_vertex(&srv.addr, &mut ws, &f, v, 0.03, 0.1, 0.0);
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
    drag_moves_vertex(&srv.addr, &mut ws, &f, v, 0.3, 0.1, 0.0);
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
    let (status, _, _) = raw_request(&srv.addr, b"POST /api/state HTTP/1.1\r\n\r\n");
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
