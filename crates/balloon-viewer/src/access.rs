//! Who may talk to the server, and how much: the `Host` and `Origin` checks, the connection cap,
//! the transport limits and the log of refusals.
//!
//! * **Host** (every request, DNS rebinding): the `Host` header must name this server by a
//!   loopback name (`localhost`, `127.0.0.1`, `[::1]`), by the address it was bound to, or by a
//!   name given with `--allow-remote`. A request without a `Host` header (or with two) is refused.
//! * **Origin** (every request that has one; cross-site WebSocket hijacking): a browser sends the
//!   page's origin with every WebSocket handshake, and it must be `http://NAME:PORT` with `NAME`
//!   one of the accepted names and `PORT` the served port: only the viewer's own page passes.
//!   A request without `Origin` does not come from a web page (scripts, `curl`, the tests) and is
//!   judged by its `Host` alone.
//! * **Connections:** at most [`MAX_CONNECTIONS`] at a time; the next one is answered 503.
//!
//! Refusals are answered with a one-line reason and logged once per kind (later ones are
//! counted and summed up when the server stops), so a hostile page cannot flood the terminal.

use std::sync::atomic::{AtomicU64, Ordering};

/// Largest accepted WebSocket message and frame, bytes: the application's limit
/// ([`crate::protocol::MAX_MESSAGE_BYTES`]), also given to the transport, so a longer message is
/// refused before it is buffered.
pub const MAX_TRANSPORT_MESSAGE: usize = crate::protocol::MAX_MESSAGE_BYTES;

/// Largest number of connections served at a time (page loads, `/api/state` calls and
/// WebSockets together; each holds a thread while open). A page needs one WebSocket and a few
/// short asset requests, so 16 leaves room for several tabs; the next connection is answered
/// `503 Service Unavailable` and closed.
pub const MAX_CONNECTIONS: usize = 16;

/// The names every viewer accepts in `Host` and `Origin`.
pub const LOOPBACK_NAMES: [&str; 3] = ["localhost", "127.0.0.1", "[::1]"];

/// Longest piece of a client's header echoed in a refusal or a log line, characters.
const MAX_ECHO: usize = 80;

/// Why a request was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefusalKind {
    /// The `Host` header is missing, repeated or names another server.
    Host,
    /// The `Origin` header is not the viewer's own page.
    Origin,
    /// Too many connections.
    Busy,
}

impl RefusalKind {
    const ALL: [Self; 3] = [Self::Host, Self::Origin, Self::Busy];

    fn index(self) -> usize {
        match self {
            Self::Host => 0,
            Self::Origin => 1,
            Self::Busy => 2,
        }
    }

    fn label(self) -> &'static str {
        match self {
            Self::Host => "bad Host",
            Self::Origin => "bad Origin",
            Self::Busy => "too many connections",
        }
    }
}

/// A refused request: its kind and the one-line reason sent back.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Refusal {
    /// What was wrong.
    pub kind: RefusalKind,
    /// One line for the client and the log.
    pub reason: String,
}

/// A client's text made safe to echo: control characters replaced by `?`, cut to
/// 80 characters.
pub fn shown(text: &str) -> String {
    let mut out: String = text
        .chars()
        .take(MAX_ECHO)
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    if text.chars().count() > MAX_ECHO {
        out.push_str("...");
    }
    out
}

/// Splits `host[:port]` (`[v6][:port]` for IPv6). `None` when malformed (an IPv6 address
/// without brackets, a port that is not a number, an empty name).
fn split_host_port(text: &str) -> Option<(&str, Option<u16>)> {
    let (name, port) = if text.starts_with('[') {
        let close = text.find(']')?;
        let (name, rest) = text.split_at(close + 1);
        match rest {
            "" => (name, None),
            _ => (name, Some(rest.strip_prefix(':')?)),
        }
    } else {
        match text.split_once(':') {
            Some((name, port)) => (name, Some(port)),
            None => (text, None),
        }
    };
    if name.is_empty() || name == "[]" {
        return None;
    }
    let port = match port {
        None => None,
        Some(p) if !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()) => Some(p.parse().ok()?),
        Some(_) => return None,
    };
    Some((name, port))
}

/// A host name as compared: lower case, without a trailing dot, IPv6 literals in brackets.
fn normalise(name: &str) -> String {
    let name = name.trim().to_ascii_lowercase();
    let name = name.strip_suffix('.').unwrap_or(&name);
    if !name.starts_with('[') && name.parse::<std::net::Ipv6Addr>().is_ok() {
        format!("[{name}]")
    } else {
        name.to_string()
    }
}

/// Checks a name given with `--allow-remote` and returns it normalised; the error says why it
/// is not a host name.
pub fn allowed_name(name: &str) -> Result<String, String> {
    let trimmed = name.trim();
    if trimmed.is_empty() {
        return Err("empty name".into());
    }
    if trimmed.contains(|c: char| c.is_whitespace() || c.is_control() || "/@*?#\\".contains(c)) {
        return Err("a host name or address has no spaces, slashes, `@`, `*`, `?` or `#`".into());
    }
    // A bare IPv6 address is fine; anything else with a colon would carry a port.
    let bare_v6 = trimmed.parse::<std::net::Ipv6Addr>().is_ok();
    if !bare_v6 {
        match split_host_port(trimmed) {
            Some((_, None)) => {}
            Some((_, Some(_))) => {
                return Err("give the name without a port (the served port is implied)".into());
            }
            None => return Err("malformed host name".into()),
        }
    }
    Ok(normalise(trimmed))
}

/// The names a server accepts in `Host` and `Origin`, and its port.
#[derive(Clone, Debug)]
pub struct Access {
    names: Vec<String>,
    port: u16,
}

impl Access {
    /// The loopback names, the bound address `bind_host` (unless it is the unspecified
    /// `0.0.0.0` / `::`) and `allowed` (already checked by [`allowed_name`]), for `port`.
    pub fn new(bind_host: &str, port: u16, allowed: &[String]) -> Self {
        let mut names: Vec<String> = LOOPBACK_NAMES.iter().map(|s| s.to_string()).collect();
        let unspecified = bind_host
            .trim_matches(|c| c == '[' || c == ']')
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_unspecified());
        if !unspecified && !bind_host.trim().is_empty() {
            names.push(normalise(bind_host));
        }
        names.extend(allowed.iter().map(|n| normalise(n)));
        names.sort();
        names.dedup();
        Self { names, port }
    }

    /// The accepted names, sorted.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    fn accepts(&self, name: &str) -> bool {
        let name = normalise(name);
        self.names.contains(&name)
    }

    fn listed(&self) -> String {
        self.names.join(", ")
    }

    /// Checks the `Host` headers of a request (all of them: there must be exactly one).
    pub fn check_host(&self, hosts: &[&str]) -> Result<(), Refusal> {
        let refuse = |reason: String| Refusal {
            kind: RefusalKind::Host,
            reason,
        };
        let host = match hosts {
            [] => return Err(refuse("refused: the request has no Host header".into())),
            [one] => one.trim(),
            _ => {
                return Err(refuse(
                    "refused: the request has more than one Host header".into(),
                ));
            }
        };
        match split_host_port(host) {
            Some((name, _)) if self.accepts(name) => Ok(()),
            _ => Err(refuse(format!(
                "refused: Host `{}` is not a name of this viewer (accepted: {}; --allow-remote adds names)",
                shown(host),
                self.listed()
            ))),
        }
    }

    /// Checks the `Origin` headers of a request: none (not a web page), or exactly one naming
    /// this viewer's page, `http://NAME:PORT`.
    pub fn check_origin(&self, origins: &[&str]) -> Result<(), Refusal> {
        let refuse = |reason: String| Refusal {
            kind: RefusalKind::Origin,
            reason,
        };
        let origin = match origins {
            [] => return Ok(()),
            [one] => one.trim(),
            _ => {
                return Err(refuse(
                    "refused: the request has more than one Origin header".into(),
                ));
            }
        };
        let ours = origin
            .get(..7)
            .filter(|scheme| scheme.eq_ignore_ascii_case("http://"))
            .and_then(|_| split_host_port(&origin[7..]))
            .is_some_and(|(name, port)| self.accepts(name) && port.unwrap_or(80) == self.port);
        if ours {
            Ok(())
        } else {
            Err(refuse(format!(
                "refused: Origin `{}` is not this viewer's page (http://NAME:{} with NAME one of {})",
                shown(origin),
                self.port,
                self.listed()
            )))
        }
    }
}

/// Counts refusals; the first of each kind is logged.
#[derive(Debug, Default)]
pub struct RefusalLog {
    counts: [AtomicU64; 3],
}

impl RefusalLog {
    /// Records `refusal`; returns the log line when it is the first of its kind (the caller
    /// prints it).
    pub fn record(&self, refusal: &Refusal) -> Option<String> {
        let n = self.counts[refusal.kind.index()].fetch_add(1, Ordering::Relaxed);
        (n == 0).then(|| {
            format!(
                "balloon view: {} (further refusals of this kind are counted, not logged)",
                refusal.reason
            )
        })
    }

    /// How many refusals of `kind` there were.
    pub fn count(&self, kind: RefusalKind) -> u64 {
        self.counts[kind.index()].load(Ordering::Relaxed)
    }

    /// `refused N requests (bad Host a, ...)`, or `None` when there was none.
    pub fn summary(&self) -> Option<String> {
        let parts: Vec<String> = RefusalKind::ALL
            .iter()
            .filter(|k| self.count(**k) > 0)
            .map(|k| format!("{} {}", k.label(), self.count(*k)))
            .collect();
        let total: u64 = RefusalKind::ALL.iter().map(|k| self.count(*k)).sum();
        (total > 0).then(|| format!("refused {total} requests ({})", parts.join(", ")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn access() -> Access {
        Access::new("127.0.0.1", 8080, &[])
    }

    #[test]
    fn loopback_hosts_pass_and_others_are_refused() {
        let a = access();
        for ok in [
            "localhost:8080",
            "LOCALHOST",
            "127.0.0.1:8080",
            "[::1]:8080",
            "localhost.:8080",
        ] {
            assert_eq!(a.check_host(&[ok]), Ok(()), "{ok}");
        }
        for bad in [
            "evil.example:8080",
            "127.0.0.1.evil.example",
            "::1",
            "",
            "localhost:port",
            "[::1",
        ] {
            let r = a.check_host(&[bad]).unwrap_err();
            assert_eq!(r.kind, RefusalKind::Host);
            assert!(
                r.reason.contains("not a name of this viewer"),
                "{}",
                r.reason
            );
        }
        assert!(a.check_host(&[]).unwrap_err().reason.contains("no Host"));
        assert!(
            a.check_host(&["localhost", "evil.example"])
                .unwrap_err()
                .reason
                .contains("more than one")
        );
    }

    #[test]
    fn only_the_viewers_own_page_is_an_accepted_origin() {
        let a = access();
        assert_eq!(a.check_origin(&[]), Ok(()));
        for ok in [
            "http://127.0.0.1:8080",
            "http://localhost:8080",
            "HTTP://[::1]:8080",
        ] {
            assert_eq!(a.check_origin(&[ok]), Ok(()), "{ok}");
        }
        for bad in [
            "http://evil.example:8080",
            "http://127.0.0.1:8081",
            "http://127.0.0.1",
            "https://127.0.0.1:8080",
            "null",
            "file://",
            "http://localhost:8080/path",
        ] {
            let r = a.check_origin(&[bad]).unwrap_err();
            assert_eq!(r.kind, RefusalKind::Origin, "{bad}");
            assert!(r.reason.contains("http://NAME:8080"), "{}", r.reason);
        }
        // Port 80 is implied without one.
        let a80 = Access::new("127.0.0.1", 80, &[]);
        assert_eq!(a80.check_origin(&["http://localhost"]), Ok(()));
    }

    #[test]
    fn allowed_names_and_the_bound_address_are_accepted() {
        let names = ["MyBox.lan", "192.168.1.5", "fe80::1"]
            .map(|n| allowed_name(n).unwrap())
            .to_vec();
        assert_eq!(names, ["mybox.lan", "192.168.1.5", "[fe80::1]"]);
        let a = Access::new("127.0.0.2", 9000, &names);
        for ok in ["mybox.lan:9000", "127.0.0.2:9000", "[fe80::1]:9000"] {
            assert_eq!(a.check_host(&[ok]), Ok(()), "{ok}");
        }
        assert_eq!(a.check_origin(&["http://mybox.lan:9000"]), Ok(()));
        // The unspecified address is no name.
        let any = Access::new("0.0.0.0", 9000, &[]);
        assert!(any.check_host(&["0.0.0.0:9000"]).is_err());
        assert_eq!(any.names(), ["127.0.0.1", "[::1]", "localhost"]);
        for bad in ["", "a b", "evil/x", "host:80", "*", "user@host"] {
            assert!(allowed_name(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn echoed_headers_are_cut_and_cleaned() {
        let a = access();
        let long = format!("\x1b[31m{}", "x".repeat(10_000));
        let r = a.check_host(&[&long]).unwrap_err().reason;
        assert!(!r.contains('\x1b') && r.len() < 400, "{r}");
        assert_eq!(shown("a\tb"), "a?b");
    }

    #[test]
    fn the_first_refusal_of_each_kind_is_logged_and_all_are_counted() {
        let log = RefusalLog::default();
        let host = Refusal {
            kind: RefusalKind::Host,
            reason: "refused: x".into(),
        };
        assert!(log.record(&host).is_some());
        assert!(log.record(&host).is_none());
        let busy = Refusal {
            kind: RefusalKind::Busy,
            reason: "busy".into(),
        };
        assert!(log.record(&busy).is_some());
        assert_eq!(log.count(RefusalKind::Host), 2);
        assert_eq!(
            log.summary().unwrap(),
            "refused 3 requests (bad Host 2, too many connections 1)"
        );
        assert_eq!(RefusalLog::default().summary(), None);
    }
}
