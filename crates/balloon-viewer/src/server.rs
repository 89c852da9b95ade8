//! The HTTP side: one thread per connection, embedded assets, `/api/state`, and the WebSocket
//! session that forwards client messages to the simulation thread and streams frames back.

use crate::access::{
    Access, MAX_CONNECTIONS, MAX_TRANSPORT_MESSAGE, Refusal, RefusalKind, RefusalLog, shown,
};
use crate::protocol::{ACK_TIMEOUT, ClientMessage, error_message, parse_client_message};
use crate::runner::{Command, FRAME_INTERVAL, Shared};
use include_dir::{Dir, include_dir};
use serde_json::Value;
use std::io::{ErrorKind, Read, Write};
use std::net::TcpStream;
use std::sync::Arc;
use std::sync::mpsc::{self, Sender};
use std::time::{Duration, Instant};
use tungstenite::protocol::WebSocketConfig;
use tungstenite::protocol::frame::CloseFrame;
use tungstenite::protocol::frame::coding::CloseCode;
use tungstenite::{Message, WebSocket};

/// The page's files (index.html, app.js, style.css, vendor/...), embedded at build time.
static WEB: Dir<'_> = include_dir!("$CARGO_MANIFEST_DIR/web");

/// Largest accepted HTTP request head, bytes: a longer request line is answered 414, longer
/// headers 431.
const MAX_HEAD: usize = 16 * 1024;

/// After an error answer, how long and how much of the rest of the request is read and
/// dropped before the connection is closed, so that closing with unread input does not reset
/// the connection before the client has read the answer.
const LINGER: (Duration, usize) = (Duration::from_secs(1), 1 << 20);

/// The content type of a served file, by extension.
pub fn content_type(path: &str) -> &'static str {
    let ext = path.rsplit_once('.').map(|(_, e)| e).unwrap_or("");
    match ext.to_ascii_lowercase().as_str() {
        "html" | "htm" => "text/html; charset=utf-8",
        "js" | "mjs" => "text/javascript; charset=utf-8",
        "css" => "text/css; charset=utf-8",
        "json" | "map" => "application/json",
        "svg" => "image/svg+xml",
        "png" => "image/png",
        "ico" => "image/x-icon",
        "wasm" => "application/wasm",
        "woff2" => "font/woff2",
        "txt" | "md" => "text/plain; charset=utf-8",
        _ => "application/octet-stream",
    }
}

/// An embedded asset by URL path (`/` is `index.html`); `None` when there is no such file or the
/// path tries to leave the folder.
pub fn asset(path: &str) -> Option<&'static [u8]> {
    let rel = path.trim_start_matches('/');
    let rel = if rel.is_empty() { "index.html" } else { rel };
    if rel.split('/').any(|s| s == ".." || s.is_empty()) {
        return None;
    }
    WEB.get_file(rel).map(|f| f.contents())
}

/// A parsed request line and headers.
#[derive(Debug, PartialEq)]
pub struct RequestHead {
    /// Method (`GET`).
    pub method: String,
    /// Path without the query.
    pub path: String,
    /// Query string (after `?`), empty when none.
    pub query: String,
    /// Whether it asks for a WebSocket upgrade.
    pub upgrade: bool,
    /// Values of its `Host` headers (one in a well-formed request).
    pub hosts: Vec<String>,
    /// Values of its `Origin` headers (browsers send one with WebSocket handshakes and
    /// cross-origin requests).
    pub origins: Vec<String>,
    /// Its `Content-Length` (`u64::MAX` for a longer number), if it gives one.
    pub content_length: Option<u64>,
    /// Whether it has a `Transfer-Encoding` header (a body of unknown length).
    pub transfer_encoding: bool,
    /// Length of the head in bytes (up to and including the blank line).
    pub length: usize,
}

impl RequestHead {
    /// Whether the request announces a body (the viewer never reads one).
    pub fn has_body(&self) -> bool {
        self.transfer_encoding || self.content_length.is_some_and(|n| n > 0)
    }
}

/// The status of a request head that [`parse_head`] refuses (`buf`: what was read of it):
/// `414 URI Too Long` when its request line alone fills [`MAX_HEAD`], `431 Request Header
/// Fields Too Large` when its headers do, `400 Bad Request` otherwise.
pub fn head_error_status(buf: &[u8]) -> &'static str {
    if buf.len() < MAX_HEAD || buf.windows(4).any(|w| w == b"\r\n\r\n") {
        "400 Bad Request"
    } else if buf.windows(2).any(|w| w == b"\r\n") {
        "431 Request Header Fields Too Large"
    } else {
        "414 URI Too Long"
    }
}

/// Parses an HTTP/1.x request head from `buf`. `Ok(None)`: incomplete; `Err`: malformed (the
/// text says why).
pub fn parse_head(buf: &[u8]) -> Result<Option<RequestHead>, String> {
    let Some(end) = buf.windows(4).position(|w| w == b"\r\n\r\n") else {
        if buf.len() >= MAX_HEAD {
            return Err(format!("request head longer than {MAX_HEAD} bytes"));
        }
        return Ok(None);
    };
    let head = std::str::from_utf8(&buf[..end]).map_err(|_| "request head is not UTF-8")?;
    let mut lines = head.split("\r\n");
    let line = lines.next().unwrap_or("");
    let parts: Vec<&str> = line.split(' ').collect();
    let [method, target, version] = parts[..] else {
        return Err(format!("malformed request line `{}`", shown(line)));
    };
    if !version.starts_with("HTTP/1.") {
        return Err(format!("unsupported protocol `{}`", shown(version)));
    }
    if !target.starts_with('/') {
        return Err(format!("malformed request target `{}`", shown(target)));
    }
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let mut upgrade = false;
    let (mut content_length, mut transfer_encoding) = (None, false);
    let (mut hosts, mut origins) = (Vec::new(), Vec::new());
    for h in lines {
        let Some((k, v)) = h.split_once(':') else {
            return Err(format!("malformed header line `{}`", shown(h)));
        };
        let (k, v) = (k.trim(), v.trim());
        if k.eq_ignore_ascii_case("upgrade") && v.eq_ignore_ascii_case("websocket") {
            upgrade = true;
        } else if k.eq_ignore_ascii_case("host") {
            hosts.push(v.to_string());
        } else if k.eq_ignore_ascii_case("origin") {
            origins.push(v.to_string());
        } else if k.eq_ignore_ascii_case("content-length") {
            if v.is_empty() || !v.bytes().all(|b| b.is_ascii_digit()) {
                return Err(format!("malformed Content-Length `{}`", shown(v)));
            }
            content_length = Some(v.parse().unwrap_or(u64::MAX));
        } else if k.eq_ignore_ascii_case("transfer-encoding") {
            transfer_encoding = true;
        }
    }
    Ok(Some(RequestHead {
        method: method.to_string(),
        path: path.to_string(),
        query: query.to_string(),
        upgrade,
        hosts,
        origins,
        content_length,
        transfer_encoding,
        length: end + 4,
    }))
}

fn respond(stream: &mut TcpStream, status: &str, ctype: &str, body: &[u8]) {
    respond_with(stream, status, ctype, &[], body);
}

/// Answers with `status`, the body and the extra header lines `headers` (without line ends).
fn respond_with(stream: &mut TcpStream, status: &str, ctype: &str, headers: &[&str], body: &[u8]) {
    let extra: String = headers.iter().map(|h| format!("{h}\r\n")).collect();
    let head = format!(
        "HTTP/1.1 {status}\r\nContent-Type: {ctype}\r\nContent-Length: {}\r\n{extra}Cache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    );
    let _ = stream
        .write_all(head.as_bytes())
        .and_then(|()| stream.write_all(body))
        .and_then(|()| stream.flush());
}

fn respond_error(stream: &mut TcpStream, status: &str, message: &str) {
    let body = serde_json::json!({"error": message}).to_string();
    respond(stream, status, "application/json", body.as_bytes());
}

/// Answers an error and closes politely: the answer is sent, the writing half shut, and what
/// the client still sends (the rest of a long head, a body) is read and dropped for up to
/// [`LINGER`], so that the client reads the answer instead of a reset connection.
fn reject(stream: &mut TcpStream, status: &str, message: &str) {
    respond_error(stream, status, message);
    linger(stream);
}

fn linger(stream: &mut TcpStream) {
    let _ = stream.shutdown(std::net::Shutdown::Write);
    let _ = stream.set_read_timeout(Some(Duration::from_millis(100)));
    let deadline = Instant::now() + LINGER.0;
    let mut chunk = [0u8; 8192];
    let mut dropped = 0;
    while Instant::now() < deadline && dropped < LINGER.1 {
        match stream.read(&mut chunk) {
            Ok(0) => return,
            Ok(n) => dropped += n,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(_) => return,
        }
    }
}

/// The `/api/state` body for `query` (`vertex=I` adds that vertex), or a 400 message.
pub fn state_json(shared: &Shared, query: &str) -> Result<String, String> {
    let p = shared.lock();
    let mut state = p.state.clone();
    let positions = p.positions.clone();
    drop(p);
    for pair in query.split('&').filter(|s| !s.is_empty()) {
        let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
        match k {
            "vertex" => {
                let n = positions.len() / 3;
                let i: usize = v.parse().map_err(|_| {
                    format!(
                        "query `vertex={v}`: expected a vertex index 0..{}",
                        n.max(1) - 1
                    )
                })?;
                if i >= n {
                    return Err(format!(
                        "query `vertex={i}`: out of range (the body has {n} vertices)"
                    ));
                }
                state.insert(
                    "vertex".into(),
                    serde_json::json!({
                        "index": i,
                        "position": [positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]],
                    }),
                );
            }
            other => return Err(format!("unknown query parameter `{other}` (known: vertex)")),
        }
    }
    Ok(Value::Object(state).to_string())
}

/// What every connection thread needs: the simulation's published data, the command channel,
/// the access rules and the refusal log.
pub struct Context {
    /// The published data.
    pub shared: Arc<Shared>,
    /// Commands for the simulation thread.
    pub commands: Sender<Command>,
    /// Accepted `Host` / `Origin` names and the port.
    pub access: Access,
    /// Refusals counted (the first of each kind logged).
    pub refusals: RefusalLog,
}

impl Context {
    /// Answers `refusal` with `status` and logs it if it is the first of its kind.
    fn refuse(&self, stream: &mut TcpStream, status: &str, refusal: &Refusal) {
        if let Some(line) = self.refusals.record(refusal) {
            eprintln!("{line}");
        }
        respond_error(stream, status, &refusal.reason);
    }
}

/// The WebSocket settings: the transport refuses messages and frames longer than the
/// application's limit before buffering them ([`MAX_TRANSPORT_MESSAGE`]).
pub fn websocket_config() -> WebSocketConfig {
    WebSocketConfig::default()
        .max_message_size(Some(MAX_TRANSPORT_MESSAGE))
        .max_frame_size(Some(MAX_TRANSPORT_MESSAGE))
}

/// Reads (consumes) the request head of `stream` until its blank line, [`MAX_HEAD`] bytes or
/// `wait`, so that an answer sent next is not lost to a reset on close.
fn drain_head(stream: &mut TcpStream, wait: Duration) {
    let deadline = Instant::now() + wait;
    let mut head = Vec::new();
    let mut chunk = [0u8; 1024];
    let _ = stream.set_read_timeout(Some(Duration::from_millis(50)));
    while Instant::now() < deadline && head.len() < MAX_HEAD {
        match stream.read(&mut chunk) {
            Ok(0) => return,
            Ok(n) => {
                head.extend_from_slice(&chunk[..n]);
                if head.windows(4).any(|w| w == b"\r\n\r\n") {
                    return;
                }
            }
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(_) => return,
        }
    }
}

/// Answers a connection beyond [`MAX_CONNECTIONS`] with a 503 (on the accept loop's refusal
/// thread: it reads at most the request head, for at most half a second).
pub fn refuse_busy(mut stream: TcpStream, context: &Context) {
    let _ = stream.set_write_timeout(Some(Duration::from_millis(500)));
    drain_head(&mut stream, Duration::from_millis(500));
    let refusal = Refusal {
        kind: RefusalKind::Busy,
        reason: format!(
            "refused: too many connections (the viewer serves at most {MAX_CONNECTIONS} at a time); close another page and retry"
        ),
    };
    context.refuse(&mut stream, "503 Service Unavailable", &refusal);
    let _ = stream.shutdown(std::net::Shutdown::Write);
}

/// Serves one connection (run on its own thread).
pub fn handle_connection(mut stream: TcpStream, context: &Context) {
    let _ = stream.set_read_timeout(Some(Duration::from_secs(5)));
    let _ = stream.set_write_timeout(Some(Duration::from_secs(5)));
    // Peek the head (the WebSocket handshake reads it again itself).
    let mut buf = vec![0u8; MAX_HEAD];
    let deadline = Instant::now() + Duration::from_secs(5);
    let head = loop {
        let n = match stream.peek(&mut buf) {
            Ok(0) => return,
            Ok(n) => n,
            Err(_) => return,
        };
        match parse_head(&buf[..n]) {
            Ok(Some(h)) => break h,
            Ok(None) if Instant::now() < deadline && n < MAX_HEAD => {
                std::thread::sleep(Duration::from_millis(5));
            }
            Ok(None) => {
                let _ = stream.read(&mut buf[..n]);
                reject(&mut stream, "400 Bad Request", "incomplete request head");
                return;
            }
            Err(e) => {
                // Consume what was peeked (and, in `reject`, what follows), so closing does not
                // reset the connection before the client reads the answer.
                let status = head_error_status(&buf[..n]);
                let _ = stream.read(&mut buf[..n]);
                let message = match status {
                    "414 URI Too Long" => format!(
                        "request line longer than {MAX_HEAD} bytes (the viewer's URLs are short)"
                    ),
                    "431 Request Header Fields Too Large" => {
                        format!("request headers longer than {MAX_HEAD} bytes")
                    }
                    _ => e,
                };
                reject(&mut stream, status, &message);
                return;
            }
        }
    };
    // DNS rebinding and cross-site requests are refused before anything else is looked at.
    let hosts: Vec<&str> = head.hosts.iter().map(String::as_str).collect();
    let origins: Vec<&str> = head.origins.iter().map(String::as_str).collect();
    if let Err(refusal) = context
        .access
        .check_host(&hosts)
        .and_then(|()| context.access.check_origin(&origins))
    {
        let _ = stream.read_exact(&mut buf[..head.length]);
        context.refuse(&mut stream, "403 Forbidden", &refusal);
        linger(&mut stream);
        return;
    }
    if head.has_body() {
        let _ = stream.read_exact(&mut buf[..head.length]);
        let size = match (head.transfer_encoding, head.content_length) {
            (false, Some(n)) => format!("a body of {n} bytes"),
            _ => "a body".to_string(),
        };
        reject(
            &mut stream,
            "413 Payload Too Large",
            &format!("the request has {size}; the viewer takes none (use GET)"),
        );
        return;
    }
    if head.path == "/ws" {
        if !head.upgrade || head.method != "GET" {
            let _ = stream.read_exact(&mut buf[..head.length]);
            reject(
                &mut stream,
                "400 Bad Request",
                "/ws expects a WebSocket upgrade (GET with `Upgrade: websocket`)",
            );
            return;
        }
        match tungstenite::accept_with_config(stream, Some(websocket_config())) {
            Ok(ws) => websocket_session(ws, &context.shared, &context.commands),
            Err(e) => eprintln!("balloon view: WebSocket handshake failed: {e}"),
        }
        return;
    }
    let _ = stream.read_exact(&mut buf[..head.length]);
    if head.method != "GET" && head.method != "HEAD" {
        reject(
            &mut stream,
            "405 Method Not Allowed",
            &format!("method {} is not supported (use GET)", shown(&head.method)),
        );
        return;
    }
    if head.path == "/api/scenario" {
        let scenario = context.shared.lock().scenario.clone();
        match scenario {
            Some(text) => respond_with(
                &mut stream,
                "200 OK",
                "application/toml; charset=utf-8",
                &["Content-Disposition: attachment; filename=\"scenario.toml\""],
                if head.method == "HEAD" {
                    &[][..]
                } else {
                    text.as_bytes()
                },
            ),
            None => respond_error(
                &mut stream,
                "404 Not Found",
                "this view's set-up (the built-in volumetric body) has no scenario to save: start it from a scenario file (`balloon view SCENARIO.toml`) to save one",
            ),
        }
        return;
    }
    if head.path == "/api/state" {
        match state_json(&context.shared, &head.query) {
            Ok(body) => respond(&mut stream, "200 OK", "application/json", body.as_bytes()),
            Err(e) => respond_error(&mut stream, "400 Bad Request", &e),
        }
        return;
    }
    match asset(&head.path) {
        Some(body) => {
            let path = if head.path == "/" {
                "index.html"
            } else {
                &head.path
            };
            let body = if head.method == "HEAD" { &[][..] } else { body };
            respond(&mut stream, "200 OK", content_type(path), body);
        }
        None => respond_error(
            &mut stream,
            "404 Not Found",
            &format!("no such file `{}`", shown(&head.path)),
        ),
    }
}

fn is_timeout(e: &tungstenite::Error) -> bool {
    matches!(e, tungstenite::Error::Io(io) if matches!(io.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut))
}

/// Sends `text`; `Ok(false)` when the socket is congested (the message stays buffered and is
/// flushed later, newer frames are dropped meanwhile); `Err` when the connection is gone.
fn send(ws: &mut WebSocket<TcpStream>, text: &str) -> Result<bool, ()> {
    match ws.send(Message::text(text)) {
        Ok(()) => Ok(true),
        Err(e) if is_timeout(&e) => Ok(false),
        Err(_) => Err(()),
    }
}

/// One connection's colour-field choice, counted in [`crate::runner::Published::scalar_interest`]
/// so that the frames carry it; the count is dropped with the connection.
struct ScalarChoice<'a> {
    shared: &'a Shared,
    chosen: Option<&'static str>,
}

impl ScalarChoice<'_> {
    /// Chooses `name` if the system has it; otherwise the error text for the client.
    fn choose(&mut self, name: &str) -> Result<(), String> {
        let mut p = self.shared.lock();
        let Some(&field) = p.scalar_fields.iter().find(|f| **f == name) else {
            return Err(format!(
                "unknown scalar field `{name}` (this system has: {})",
                p.scalar_fields.join(", ")
            ));
        };
        if let Some(old) = self.chosen.replace(field) {
            release(&mut p.scalar_interest, old);
        }
        *p.scalar_interest.entry(field).or_insert(0) += 1;
        Ok(())
    }
}

fn release(interest: &mut std::collections::BTreeMap<&'static str, usize>, name: &'static str) {
    if let Some(n) = interest.get_mut(name) {
        *n -= 1;
        if *n == 0 {
            interest.remove(name);
        }
    }
}

impl Drop for ScalarChoice<'_> {
    fn drop(&mut self) {
        if let Some(old) = self.chosen.take() {
            release(&mut self.shared.lock().scalar_interest, old);
        }
    }
}

fn websocket_session(mut ws: WebSocket<TcpStream>, shared: &Shared, commands: &Sender<Command>) {
    let _ = ws
        .get_mut()
        .set_read_timeout(Some(Duration::from_millis(10)));
    let _ = ws
        .get_mut()
        .set_write_timeout(Some(Duration::from_millis(200)));
    let (reply_tx, reply_rx) = mpsc::channel::<String>();
    let mut hello_generation = 0;
    let mut frame_number = 0;
    let mut broadcast_seq = shared.lock().broadcasts.last().map_or(0, |b| b.0);
    let mut last_frame = Instant::now() - FRAME_INTERVAL;
    let mut congested = false;
    // Acknowledged mode (after the client's first `ack`): the frame sent and not yet
    // acknowledged, and when it was sent.
    let mut acking = false;
    let mut unacked: Option<(u64, Instant)> = None;
    let mut scalar = ScalarChoice {
        shared,
        chosen: None,
    };
    loop {
        if shared.stopping() {
            let _ = ws.close(None);
            let _ = ws.flush();
            return;
        }
        if congested {
            match ws.flush() {
                Ok(()) => congested = false,
                Err(e) if is_timeout(&e) => {}
                Err(_) => return,
            }
        }
        if !congested {
            let mut out: Vec<Arc<String>> = Vec::new();
            while let Ok(r) = reply_rx.try_recv() {
                out.push(Arc::new(r));
            }
            {
                let p = shared.lock();
                if p.hello_generation != hello_generation {
                    hello_generation = p.hello_generation;
                    out.push(p.hello.clone());
                    frame_number = 0;
                }
                for (seq, b) in &p.broadcasts {
                    if *seq > broadcast_seq {
                        broadcast_seq = *seq;
                        out.push(b.clone());
                    }
                }
                let waiting = unacked.is_some_and(|(_, sent)| sent.elapsed() < ACK_TIMEOUT);
                if p.frame_number > frame_number
                    && last_frame.elapsed() >= FRAME_INTERVAL
                    && !waiting
                {
                    frame_number = p.frame_number;
                    last_frame = Instant::now();
                    out.push(Arc::new(p.frame.text(scalar.chosen)));
                    if acking {
                        unacked = Some((frame_number, last_frame));
                    }
                }
            }
            for m in out {
                match send(&mut ws, &m) {
                    Ok(true) => {}
                    Ok(false) => congested = true,
                    Err(()) => return,
                }
            }
        }
        match ws.read() {
            Ok(Message::Text(t)) => match parse_client_message(t.as_str()) {
                // The colour field is this connection's own choice; the simulation only has to
                // publish a frame with it soon (also while paused).
                Ok(ClientMessage::Scalar { name }) => match scalar.choose(&name) {
                    Ok(()) => {
                        if commands.send(Command::Refresh).is_err() {
                            return;
                        }
                    }
                    Err(e) => {
                        let _ = reply_tx.send(error_message(&e));
                    }
                },
                Ok(ClientMessage::Ack { frame }) => {
                    acking = true;
                    if unacked.is_some_and(|(sent, _)| frame >= sent) {
                        unacked = None;
                    }
                }
                Ok(message) => {
                    let cmd = Command::Client {
                        message,
                        reply: reply_tx.clone(),
                    };
                    if commands.send(cmd).is_err() {
                        return;
                    }
                }
                Err(e) => {
                    let _ = reply_tx.send(error_message(&e));
                }
            },
            Ok(Message::Binary(_)) => {
                let _ = reply_tx.send(error_message(
                    "binary messages are not supported; send JSON text",
                ));
            }
            Ok(Message::Close(_)) => {
                let _ = ws.flush();
                return;
            }
            Ok(_) => {}
            Err(e) if is_timeout(&e) => {}
            Err(tungstenite::Error::Protocol(p)) => {
                eprintln!("balloon view: WebSocket protocol error: {p}");
                return;
            }
            // Longer than the limit: refused by the transport before it was buffered; the
            // connection is closed with 1009 (message too big).
            Err(tungstenite::Error::Capacity(_)) => {
                let reason = format!("message longer than {MAX_TRANSPORT_MESSAGE} bytes");
                let _ = ws.close(Some(CloseFrame {
                    code: CloseCode::Size,
                    reason: reason.into(),
                }));
                let _ = ws.flush();
                return;
            }
            Err(_) => return,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_field_choices_are_checked_counted_and_released() {
        let shared = Shared::default();
        shared.lock().scalar_fields = vec!["thickness", "stretch"];
        let mut a = ScalarChoice {
            shared: &shared,
            chosen: None,
        };
        let e = a.choose("colour").unwrap_err();
        assert!(
            e.contains("unknown scalar field `colour`") && e.contains("thickness, stretch"),
            "{e}"
        );
        assert_eq!(a.chosen, None);
        a.choose("stretch").unwrap();
        {
            let mut b = ScalarChoice {
                shared: &shared,
                chosen: None,
            };
            b.choose("stretch").unwrap();
            assert_eq!(shared.lock().scalar_interest["stretch"], 2);
            b.choose("thickness").unwrap();
            assert_eq!(shared.lock().scalar_interest["stretch"], 1);
            assert_eq!(shared.lock().scalar_interest["thickness"], 1);
        }
        // `b` is gone (its connection closed): only `a`'s choice is left.
        let interest = shared.lock().scalar_interest.clone();
        assert_eq!(
            interest.into_iter().collect::<Vec<_>>(),
            vec![("stretch", 1)]
        );
        drop(a);
        assert!(shared.lock().scalar_interest.is_empty());
    }

    #[test]
    fn request_heads_parse() {
        let raw = b"GET /api/state?vertex=3 HTTP/1.1\r\nHost: x\r\n\r\nrest";
        let h = parse_head(raw).unwrap().unwrap();
        assert_eq!(h.method, "GET");
        assert_eq!(h.path, "/api/state");
        assert_eq!(h.query, "vertex=3");
        assert!(!h.upgrade);
        assert_eq!(h.length, raw.len() - 4);
        let ws = parse_head(b"GET /ws HTTP/1.1\r\nUpgrade: WebSocket\r\n\r\n")
            .unwrap()
            .unwrap();
        assert!(ws.upgrade);
        assert_eq!(parse_head(b"GET / HTTP/1.1\r\nHost: x\r\n").unwrap(), None);
    }

    #[test]
    fn malformed_heads_are_rejected() {
        for (raw, want) in [
            (&b"GARBAGE\r\n\r\n"[..], "malformed request line"),
            (b"GET / HTTP/1.1 extra\r\n\r\n", "malformed request line"),
            (b"GET / SPDY/3\r\n\r\n", "unsupported protocol"),
            (
                b"GET index.html HTTP/1.1\r\n\r\n",
                "malformed request target",
            ),
            (
                b"GET / HTTP/1.1\r\nno colon here\r\n\r\n",
                "malformed header",
            ),
            (b"GET / HTTP/1.1\r\n\xff\xfe: x\r\n\r\n", "not UTF-8"),
        ] {
            let e = parse_head(raw).unwrap_err();
            assert!(e.contains(want), "{e}");
        }
        let long = vec![b'a'; MAX_HEAD];
        assert!(parse_head(&long).unwrap_err().contains("longer"));
    }

    #[test]
    fn long_heads_and_bodies_are_told_apart() {
        assert_eq!(head_error_status(b"GARBAGE\r\n\r\n"), "400 Bad Request");
        let mut line = b"GET /".to_vec();
        line.resize(MAX_HEAD, b'a');
        assert_eq!(head_error_status(&line), "414 URI Too Long");
        let mut headers = b"GET / HTTP/1.1\r\nX: ".to_vec();
        headers.resize(MAX_HEAD, b'a');
        assert_eq!(
            head_error_status(&headers),
            "431 Request Header Fields Too Large"
        );
        let h = parse_head(b"GET / HTTP/1.1\r\nContent-Length: 0\r\n\r\n")
            .unwrap()
            .unwrap();
        assert_eq!(h.content_length, Some(0));
        assert!(!h.has_body());
        let h = parse_head(b"GET / HTTP/1.1\r\ncontent-length: 99999999999999999999999\r\n\r\n")
            .unwrap()
            .unwrap();
        assert_eq!(h.content_length, Some(u64::MAX));
        assert!(h.has_body());
        let e = parse_head(b"GET / HTTP/1.1\r\nContent-Length: -1\r\n\r\n").unwrap_err();
        assert!(e.contains("malformed Content-Length `-1`"), "{e}");
    }

    #[test]
    fn assets_and_content_types() {
        assert!(asset("/").is_some(), "web/index.html must be embedded");
        assert_eq!(asset("/"), asset("/index.html"));
        assert!(asset("/../Cargo.toml").is_none());
        assert!(asset("/nope.js").is_none());
        assert!(asset("/vendor//index.html").is_none());
        assert_eq!(content_type("a/b.js"), "text/javascript; charset=utf-8");
        assert_eq!(content_type("index.html"), "text/html; charset=utf-8");
        assert_eq!(content_type("s.CSS"), "text/css; charset=utf-8");
        assert_eq!(content_type("x.bin"), "application/octet-stream");
    }

    #[test]
    fn state_queries_are_validated() {
        let shared = Shared::default();
        {
            let mut p = shared.lock();
            p.positions = Arc::new(vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
            p.state.insert("frame".into(), Value::from(4));
        }
        let v: Value = serde_json::from_str(&state_json(&shared, "").unwrap()).unwrap();
        assert_eq!(v["frame"], 4);
        assert!(v.get("vertex").is_none());
        let v: Value = serde_json::from_str(&state_json(&shared, "vertex=1").unwrap()).unwrap();
        assert_eq!(v["vertex"]["index"], 1);
        assert_eq!(v["vertex"]["position"], serde_json::json!([3.0, 4.0, 5.0]));
        assert!(
            state_json(&shared, "vertex=2")
                .unwrap_err()
                .contains("out of range")
        );
        assert!(
            state_json(&shared, "vertex=x")
                .unwrap_err()
                .contains("vertex index")
        );
        assert!(
            state_json(&shared, "colour=red")
                .unwrap_err()
                .contains("unknown query")
        );
    }
}
