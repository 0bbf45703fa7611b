//! Who may use the server: the `Host` and `Origin` checks and the token.
//!
//! Every request passes [`check`] before it reaches a route:
//!
//! 1. **Host.** A server bound to a loopback address (`127.0.0.0/8`, `::1`) answers only
//!    requests whose `Host` header names a loopback host (`localhost`, a `127.x.y.z`
//!    address, `[::1]`) and the port it listens on. A web page that re-binds its own domain
//!    name to 127.0.0.1 (DNS rebinding) sends its own name as `Host` and is refused. A server
//!    bound to another address cannot know every name it is reached by, and accepts any
//!    `Host`: the token stands in for the check.
//! 2. **Token.** A server bound to anything but loopback (`--host 0.0.0.0`, a LAN address)
//!    requires a secret token, 128 random bits in hex ([`new_token`]), as Jupyter does: the
//!    printed URL carries it (`/?token=…`), and a request carrying the right token in its
//!    query is answered with a cookie (`raisov_token_<port>`, `HttpOnly`,
//!    `SameSite=Strict`) that the page's later requests and its WebSocket send. A request
//!    without the token, or with another one, is refused (403). A loopback server requires
//!    one only when it is given one (`--token`).
//! 3. **Origin.** The WebSocket (`/ws`) drives the simulation and streams the surface. A
//!    browser sends the `Origin` of the page that opens a WebSocket; the upgrade is accepted
//!    only from the server's own page (`Origin` equal to `http://` or `https://` and the
//!    request's `Host`) or from a client that sends no `Origin` (a program, not a page). A
//!    page of another site, open in the same browser, is refused (403) before the upgrade.
//!
//! Tokens are compared in constant time.

use axum::extract::{Request, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;

/// The access rules of one server ([module docs](self)).
#[derive(Clone, Debug)]
pub struct Access {
    port: u16,
    loopback: bool,
    token: Option<String>,
}

impl Access {
    /// The rules for a server listening on `bound`: the Host check where it is a loopback
    /// address; `token` required where given, and a new one made where `bound` is not
    /// loopback and none was given.
    pub fn for_bound(bound: SocketAddr, token: Option<String>) -> Result<Access, String> {
        let loopback = bound.ip().is_loopback();
        let token = match token {
            Some(t) => {
                check_token_text(&t)?;
                Some(t)
            }
            None if loopback => None,
            None => Some(new_token()?),
        };
        Ok(Access {
            port: bound.port(),
            loopback,
            token,
        })
    }

    /// The token clients must present, if any.
    pub fn token(&self) -> Option<&str> {
        self.token.as_deref()
    }

    /// Whether the server listens on a loopback address only.
    pub fn loopback(&self) -> bool {
        self.loopback
    }

    /// The name of the cookie that carries the token.
    pub fn cookie_name(&self) -> String {
        format!("raisov_token_{}", self.port)
    }

    /// Why a request with these headers and query is refused, or `None` when it is
    /// accepted. `websocket`: the request asks for `/ws`.
    pub fn refusal(
        &self,
        host: Option<&str>,
        origin: Option<&str>,
        query: Option<&str>,
        cookies: &[&str],
        websocket: bool,
    ) -> Option<Refusal> {
        let Some(host) = host else {
            return Some(Refusal::Host("the request names no Host".into()));
        };
        if self.loopback && !self.loopback_host(host) {
            return Some(Refusal::Host(format!(
                "Host {host:?} is not this server (it answers localhost, 127.0.0.1 or [::1] \
                 on port {})",
                self.port
            )));
        }
        if let Some(want) = &self.token {
            let given = query.and_then(|q| query_value(q, "token")).or_else(|| {
                let name = self.cookie_name();
                cookies.iter().find_map(|c| cookie_value(c, &name))
            });
            match given {
                Some(t) if same(t.as_bytes(), want.as_bytes()) => {}
                Some(_) => return Some(Refusal::Token("the token is not this server's")),
                None => {
                    return Some(Refusal::Token(
                        "this server needs its token: open the URL it printed (…/?token=…)",
                    ))
                }
            }
        }
        if websocket {
            if let Some(origin) = origin {
                let own = ["http://", "https://"]
                    .iter()
                    .any(|s| origin.eq_ignore_ascii_case(&format!("{s}{host}")));
                if !own {
                    return Some(Refusal::Origin(format!(
                        "a WebSocket from the page of {origin:?} is refused: only this \
                         server's own page may drive the simulation"
                    )));
                }
            }
        }
        None
    }

    /// Whether `host` (a Host header: name or address, and port) is a loopback name with
    /// the server's port.
    fn loopback_host(&self, host: &str) -> bool {
        let (name, port) = split_host(host);
        let port_ok = match port {
            Some(p) => p.parse::<u16>().ok() == Some(self.port),
            None => self.port == 80,
        };
        let name = name.trim_end_matches('.');
        let name_ok = name.eq_ignore_ascii_case("localhost")
            || name
                .trim_start_matches('[')
                .trim_end_matches(']')
                .parse::<IpAddr>()
                .is_ok_and(|ip| ip.is_loopback());
        port_ok && name_ok
    }
}

/// Why a request was refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// The Host header does not name this server.
    Host(String),
    /// The token is missing or wrong.
    Token(&'static str),
    /// A cross-origin WebSocket.
    Origin(String),
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::Host(m) | Refusal::Origin(m) => f.write_str(m),
            Refusal::Token(m) => f.write_str(m),
        }
    }
}

/// The middleware: refuse with 403 and the reason in words, or pass the request on (and set
/// the token cookie when the query carried the right token).
pub async fn check(State(access): State<Arc<Access>>, req: Request, next: Next) -> Response {
    let headers = req.headers();
    let text = |h: header::HeaderName| headers.get(h).and_then(|v| v.to_str().ok());
    let cookies: Vec<&str> = headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .collect();
    let query = req.uri().query();
    let websocket = req.uri().path() == "/ws";
    if let Some(r) = access.refusal(
        text(header::HOST),
        text(header::ORIGIN),
        query,
        &cookies,
        websocket,
    ) {
        let mut resp = (StatusCode::FORBIDDEN, format!("refused: {r}\n")).into_response();
        resp.headers_mut().insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("text/plain; charset=utf-8"),
        );
        return resp;
    }
    let set_cookie = access.token().is_some()
        && !websocket
        && query.and_then(|q| query_value(q, "token")).is_some();
    let mut resp = next.run(req).await;
    if set_cookie {
        if let Some(t) = access.token() {
            let c = format!(
                "{}={t}; Path=/; HttpOnly; SameSite=Strict",
                access.cookie_name()
            );
            if let Ok(v) = HeaderValue::from_str(&c) {
                resp.headers_mut().append(header::SET_COOKIE, v);
            }
        }
    }
    resp
}

/// A new token: 128 bits from the operating system's random source, in hex.
pub fn new_token() -> Result<String, String> {
    let mut b = [0u8; 16];
    getrandom::fill(&mut b).map_err(|e| format!("no random source for the token: {e}"))?;
    Ok(b.iter().map(|x| format!("{x:02x}")).collect())
}

/// A token given by the user: 16 to 128 characters of letters, digits, `-` and `_` (it
/// travels in a URL and a cookie unescaped).
pub fn check_token_text(t: &str) -> Result<(), String> {
    let ok = (16..=128).contains(&t.len())
        && t.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_');
    if ok {
        Ok(())
    } else {
        Err(format!(
            "--token: must be 16 to 128 characters of letters, digits, '-' and '_' (got {} \
             characters)",
            t.chars().count()
        ))
    }
}

/// Host and port of a Host header (`name:port`, `[v6]:port`, `name`).
fn split_host(host: &str) -> (&str, Option<&str>) {
    if let Some(rest) = host.strip_prefix('[') {
        return match rest.split_once(']') {
            Some((a, p)) => (
                &host[..a.len() + 2],
                p.strip_prefix(':').filter(|p| !p.is_empty()),
            ),
            None => (host, None),
        };
    }
    match host.rsplit_once(':') {
        Some((n, p)) if !n.contains(':') => (n, Some(p)),
        _ => (host, None),
    }
}

/// The value of `key` in a query string (`a=1&token=x`), not percent-decoded (tokens need
/// no escaping).
fn query_value<'a>(query: &'a str, key: &str) -> Option<&'a str> {
    query
        .split('&')
        .find_map(|kv| kv.strip_prefix(key)?.strip_prefix('='))
}

/// The value of cookie `name` in a Cookie header (`a=1; b=2`).
fn cookie_value<'a>(header: &'a str, name: &str) -> Option<&'a str> {
    header
        .split(';')
        .find_map(|kv| kv.trim().strip_prefix(name)?.strip_prefix('='))
}

/// Constant-time equality (the time depends on the lengths only).
fn same(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn local(port: u16) -> Access {
        Access::for_bound(([127, 0, 0, 1], port).into(), None).unwrap()
    }

    #[test]
    fn a_loopback_server_answers_loopback_hosts_on_its_port_only() {
        let a = local(8080);
        for ok in [
            "localhost:8080",
            "127.0.0.1:8080",
            "[::1]:8080",
            "LOCALHOST:8080",
            "127.1.2.3:8080",
        ] {
            assert_eq!(a.refusal(Some(ok), None, None, &[], false), None, "{ok}");
        }
        for bad in [
            "evil.example:8080",
            "localhost:8081",
            "localhost",
            "10.0.0.1:8080",
            "127.0.0.1.evil:8080",
        ] {
            assert!(
                matches!(
                    a.refusal(Some(bad), None, None, &[], false),
                    Some(Refusal::Host(_))
                ),
                "{bad}"
            );
        }
        assert!(matches!(
            a.refusal(None, None, None, &[], false),
            Some(Refusal::Host(_))
        ));
    }

    #[test]
    fn a_websocket_from_another_origin_is_refused() {
        let a = local(8080);
        let h = Some("127.0.0.1:8080");
        assert_eq!(
            a.refusal(h, Some("http://127.0.0.1:8080"), None, &[], true),
            None
        );
        assert_eq!(
            a.refusal(h, None, None, &[], true),
            None,
            "no Origin: a program"
        );
        for bad in [
            "http://evil.example",
            "http://localhost:8080",
            "null",
            "http://127.0.0.1:8081",
        ] {
            assert!(
                matches!(
                    a.refusal(h, Some(bad), None, &[], true),
                    Some(Refusal::Origin(_))
                ),
                "{bad}"
            );
        }
        // The page itself (not /ws) may be loaded from anywhere that names this host.
        assert_eq!(
            a.refusal(h, Some("http://evil.example"), None, &[], false),
            None
        );
    }

    #[test]
    fn a_server_bound_beyond_loopback_requires_its_token() {
        let a = Access::for_bound(([0, 0, 0, 0], 9000).into(), None).unwrap();
        let t = a.token().expect("a token is made").to_string();
        assert_eq!(t.len(), 32);
        let h = Some("my-host.lan:9000");
        assert!(matches!(
            a.refusal(h, None, None, &[], false),
            Some(Refusal::Token(_))
        ));
        assert!(matches!(
            a.refusal(
                h,
                None,
                Some("token=0123456789abcdef0123456789abcdef"),
                &[],
                false
            ),
            Some(Refusal::Token(_))
        ));
        assert_eq!(
            a.refusal(h, None, Some(&format!("x=1&token={t}")), &[], false),
            None
        );
        let cookie = format!("other=1; raisov_token_9000={t}");
        assert_eq!(a.refusal(h, None, None, &[&cookie], true), None);
        // Another port's cookie does not open this server.
        let wrong = format!("raisov_token_9001={t}");
        assert!(a.refusal(h, None, None, &[&wrong], false).is_some());
        // Two servers get different tokens.
        let b = Access::for_bound(([0, 0, 0, 0], 9000).into(), None).unwrap();
        assert_ne!(a.token(), b.token());
    }

    #[test]
    fn a_given_token_is_checked_and_required_on_loopback_too() {
        assert!(Access::for_bound(([127, 0, 0, 1], 1).into(), Some("short".into())).is_err());
        assert!(Access::for_bound(
            ([127, 0, 0, 1], 1).into(),
            Some("a b c d e f g h i j".into())
        )
        .is_err());
        let a = Access::for_bound(
            ([127, 0, 0, 1], 1).into(),
            Some("0123456789abcdefXYZ".into()),
        )
        .unwrap();
        assert!(a
            .refusal(Some("localhost:1"), None, None, &[], false)
            .is_some());
        assert_eq!(
            a.refusal(
                Some("localhost:1"),
                None,
                Some("token=0123456789abcdefXYZ"),
                &[],
                false
            ),
            None
        );
    }

    #[test]
    fn host_headers_split_into_name_and_port() {
        assert_eq!(split_host("a:1"), ("a", Some("1")));
        assert_eq!(split_host("[::1]:8080"), ("[::1]", Some("8080")));
        assert_eq!(split_host("[::1]"), ("[::1]", None));
        assert_eq!(split_host("a"), ("a", None));
        assert_eq!(split_host("::1"), ("::1", None));
    }
}
