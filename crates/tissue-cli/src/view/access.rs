//! Who may talk to the viewer (docs/security.md). Every request, page file or WebSocket, must
//! (1) name a host the server answers to in `Host` (loopback names and the explicit `--host`:
//! a DNS-rebinding page arrives under its own name), (2) if it carries an `Origin`, come from
//! the served origin itself (another site's page in the same browser), and (3) show the
//! session's random token, in the URL's `token` query or in the cookie the first page load
//! set. The token is what makes a non-loopback `--host` safe on a shared network.

use std::fmt;
use std::net::IpAddr;

/// Length of the random token, in bytes (hex-encoded in the URL: 64 characters).
const TOKEN_BYTES: usize = 32;

/// Why a request was turned away; its text goes to the client and the log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Refusal {
    /// `Host` missing, repeated or naming a host this server does not answer to.
    Host(String),
    /// `Origin` present and not the served origin.
    Origin(String),
    /// No token, or not this session's.
    Token,
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Refusal::Host(h) => write!(
                f,
                "Host {h:?} is not one this server answers to (loopback names or the --host \
                 address, with the port)"
            ),
            Refusal::Origin(o) => write!(f, "cross-origin request from {o:?} refused"),
            Refusal::Token => write!(
                f,
                "missing or wrong session token: open the URL `tissue view` printed"
            ),
        }
    }
}

/// How a request proved it belongs to the session.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Grant {
    /// The token was in the URL: the response sets the cookie so the page's own requests
    /// (scripts, styles, three.js) carry it.
    Query,
    /// The cookie carried it.
    Cookie,
}

/// The session's access rule: its token and the `Host` values it answers to.
#[derive(Debug, Clone)]
pub struct Access {
    token: String,
    port: u16,
    /// Lower-case `host:port` values accepted in `Host` (and `http://` + one in `Origin`).
    hosts: Vec<String>,
}

impl Access {
    /// The rule for a server bound to `host:port` with `token`.
    pub fn new(token: String, host: IpAddr, port: u16) -> Self {
        let mut names: Vec<String> = vec!["127.0.0.1".into(), "localhost".into(), "[::1]".into()];
        let explicit = url_host(host);
        if !names.contains(&explicit) {
            names.push(explicit);
        }
        let mut hosts: Vec<String> = names.iter().map(|n| format!("{n}:{port}")).collect();
        if port == 80 {
            // Browsers leave the default port out of `Host` and `Origin`.
            hosts.extend(names);
        }
        Self { token, port, hosts }
    }

    /// A rule with a fresh random token.
    pub fn random(host: IpAddr, port: u16) -> std::io::Result<Self> {
        Ok(Self::new(random_token()?, host, port))
    }

    pub fn token(&self) -> &str {
        &self.token
    }

    /// The cookie's name: per port, so two viewers on one machine do not overwrite each
    /// other's (cookies ignore ports).
    pub fn cookie_name(&self) -> String {
        format!("tissue_token_{}", self.port)
    }

    /// The `Set-Cookie` value sent with a response to a request granted by its URL.
    pub fn set_cookie(&self) -> String {
        format!(
            "{}={}; Path=/; HttpOnly; SameSite=Strict",
            self.cookie_name(),
            self.token
        )
    }

    /// Checks a complete request head (request line and headers).
    pub fn check(&self, head: &str) -> Result<Grant, Refusal> {
        let hosts: Vec<&str> = header_values(head, "host").collect();
        let host = match hosts.as_slice() {
            [h] => h.to_ascii_lowercase(),
            [] => return Err(Refusal::Host(String::new())),
            _ => return Err(Refusal::Host(hosts.join(", "))),
        };
        if !self.hosts.contains(&host) {
            return Err(Refusal::Host(host));
        }
        for origin in header_values(head, "origin") {
            if origin.to_ascii_lowercase() != format!("http://{host}") {
                return Err(Refusal::Origin(origin.to_string()));
            }
        }
        let target = head
            .lines()
            .next()
            .and_then(|l| l.split(' ').nth(1))
            .unwrap_or("");
        let query = target.split_once('?').map_or("", |(_, q)| q);
        let query = query.split('#').next().unwrap_or("");
        if query
            .split('&')
            .filter_map(|kv| kv.strip_prefix("token="))
            .any(|t| same(t, &self.token))
        {
            return Ok(Grant::Query);
        }
        let name = self.cookie_name();
        let by_cookie = header_values(head, "cookie")
            .flat_map(|c| c.split(';'))
            .filter_map(|kv| kv.trim().split_once('='))
            .any(|(k, v)| k == name && same(v, &self.token));
        if by_cookie {
            Ok(Grant::Cookie)
        } else {
            Err(Refusal::Token)
        }
    }
}

/// How `host` is written in a URL (IPv6 in brackets).
pub fn url_host(host: IpAddr) -> String {
    match host {
        IpAddr::V6(h) => format!("[{h}]"),
        IpAddr::V4(h) => h.to_string(),
    }
}

/// The values of every header named `name` (case-insensitive), trimmed.
fn header_values<'a>(head: &'a str, name: &'a str) -> impl Iterator<Item = &'a str> + 'a {
    head.lines().skip(1).filter_map(move |l| {
        let (k, v) = l.split_once(':')?;
        k.trim().eq_ignore_ascii_case(name).then(|| v.trim())
    })
}

/// Compares in time independent of where the first difference is.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

/// A hex token from the operating system's random source.
fn random_token() -> std::io::Result<String> {
    let mut bytes = [0u8; TOKEN_BYTES];
    getrandom::fill(&mut bytes).map_err(std::io::Error::other)?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::Ipv4Addr;

    fn rule() -> Access {
        Access::new("abc123".into(), IpAddr::V4(Ipv4Addr::LOCALHOST), 8765)
    }

    #[test]
    fn the_token_comes_by_query_or_cookie() {
        let a = rule();
        let q = "GET /?token=abc123 HTTP/1.1\r\nHost: 127.0.0.1:8765\r\n\r\n";
        assert_eq!(a.check(q), Ok(Grant::Query));
        let c = "GET /src/main.js HTTP/1.1\r\nHost: localhost:8765\r\n\
                 Cookie: a=b; tissue_token_8765=abc123\r\n\r\n";
        assert_eq!(a.check(c), Ok(Grant::Cookie));
        for bad in [
            "GET / HTTP/1.1\r\nHost: 127.0.0.1:8765\r\n\r\n",
            "GET /?token=abc124 HTTP/1.1\r\nHost: 127.0.0.1:8765\r\n\r\n",
            "GET /?token=abc12 HTTP/1.1\r\nHost: 127.0.0.1:8765\r\n\r\n",
            "GET /?xtoken=abc123 HTTP/1.1\r\nHost: 127.0.0.1:8765\r\n\r\n",
            "GET / HTTP/1.1\r\nHost: 127.0.0.1:8765\r\nCookie: tissue_token_9999=abc123\r\n\r\n",
        ] {
            assert_eq!(a.check(bad), Err(Refusal::Token), "{bad}");
        }
    }

    #[test]
    fn host_and_origin_are_this_server() {
        let a = rule();
        let ok = |h: &str| format!("GET /?token=abc123 HTTP/1.1\r\n{h}\r\n\r\n");
        for good in [
            "Host: 127.0.0.1:8765",
            "host: LOCALHOST:8765",
            "Host: [::1]:8765",
            "Host: 127.0.0.1:8765\r\nOrigin: http://127.0.0.1:8765",
        ] {
            assert!(a.check(&ok(good)).is_ok(), "{good}");
        }
        for (bad, why) in [
            ("", "host"),
            ("Host: evil.example:8765", "host"),
            ("Host: 127.0.0.1:8766", "host"),
            ("Host: 127.0.0.1", "host"),
            ("Host: 127.0.0.1:8765\r\nHost: evil.example:8765", "host"),
            (
                "Host: 127.0.0.1:8765\r\nOrigin: http://evil.example",
                "origin",
            ),
            ("Host: 127.0.0.1:8765\r\nOrigin: null", "origin"),
            (
                "Host: 127.0.0.1:8765\r\nOrigin: http://localhost:8765",
                "origin",
            ),
        ] {
            let got = a.check(&ok(bad));
            let kind = match got {
                Err(Refusal::Host(_)) => "host",
                Err(Refusal::Origin(_)) => "origin",
                _ => "other",
            };
            assert_eq!(kind, why, "{bad}: {got:?}");
        }
    }

    #[test]
    fn an_explicit_host_is_answered_and_tokens_are_random() {
        let a = Access::new(
            "t".into(),
            "192.168.1.5".parse().unwrap_or(IpAddr::from([0; 4])),
            80,
        );
        let h = "GET /?token=t HTTP/1.1\r\nHost: 192.168.1.5\r\n\r\n";
        assert_eq!(a.check(h), Ok(Grant::Query));
        let (x, y) = (random_token(), random_token());
        assert!(matches!((&x, &y), (Ok(x), Ok(y)) if x != y && x.len() == 2 * TOKEN_BYTES));
    }
}
