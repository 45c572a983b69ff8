//! Bearer-token authentication and the start-up rule about where the API may listen.
//!
//! In: the token from `KESTREL_API_TOKEN`, the config's `[api] token` or `token_file`; each
//! request's `Authorization: Bearer` header (or `?token=` on the WebSocket). Out: the request
//! passes, or `401 unauthorized`. Listening beyond loopback without a token is refused.

use super::error::ApiError;
use super::ApiState;
use crate::config::ApiSection;
use axum::extract::{Request, State};
use axum::http::header::{AUTHORIZATION, HOST, ORIGIN};
use axum::middleware::Next;
use axum::response::Response;
use std::net::{IpAddr, SocketAddr};

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum AuthError {
    #[error("cannot read the API token file {path}: {message}")]
    TokenFile { path: String, message: String },
    #[error("the API token is empty")]
    EmptyToken,
    #[error("refusing to listen on {0} without an API token: set KESTREL_API_TOKEN or [api] token / token_file, or listen on 127.0.0.1")]
    OpenBeyondLoopback(SocketAddr),
}

/// The token, from the environment value (if set), then the config.
pub fn resolve_token(env: Option<String>, api: &ApiSection) -> Result<Option<String>, AuthError> {
    let token = match (env, &api.token, &api.token_file) {
        (Some(t), _, _) => Some(t),
        (None, Some(t), _) => Some(t.clone()),
        (None, None, Some(path)) => {
            let text = std::fs::read_to_string(path).map_err(|e| AuthError::TokenFile {
                path: path.display().to_string(),
                message: e.to_string(),
            })?;
            Some(text.trim().to_string())
        }
        (None, None, None) => None,
    };
    match token {
        Some(t) if t.trim().is_empty() => Err(AuthError::EmptyToken),
        other => Ok(other),
    }
}

/// Without a token the API may only listen on loopback.
pub fn check_listen(addr: SocketAddr, token: Option<&str>) -> Result<(), AuthError> {
    if token.is_none() && !addr.ip().is_loopback() {
        return Err(AuthError::OpenBeyondLoopback(addr));
    }
    Ok(())
}

/// Compares without stopping at the first difference, so timing tells nothing.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// The `token=` query parameter, decoded as browsers encode it (form encoding: `+` is a space,
/// `%2B` a plus), so a base64 token with `+ / =` arrives intact.
fn query_token(query: Option<&str>) -> Option<String> {
    let raw = query?
        .split('&')
        .find_map(|pair| pair.strip_prefix("token="))?;
    let spaced = raw.replace('+', " ");
    percent_encoding::percent_decode_str(&spaced)
        .decode_utf8()
        .ok()
        .map(|t| t.into_owned())
}

/// The token of an `Authorization` header; the scheme is case-insensitive (RFC 7235).
fn bearer_token(header: &str) -> Option<&str> {
    let (scheme, token) = header.trim().split_once(' ')?;
    scheme.eq_ignore_ascii_case("bearer").then(|| token.trim())
}

/// Browsers cannot set headers on a WebSocket: only that route takes the token in its query.
const QUERY_TOKEN_ROUTE: &str = "/api/ws";

/// Middleware: every protected route needs the bearer token (when one is configured).
pub async fn require_token(
    State(state): State<ApiState>,
    request: Request,
    next: Next,
) -> Result<Response, ApiError> {
    let Some(expected) = state.token.as_deref() else {
        return Ok(next.run(request).await);
    };
    let header = request
        .headers()
        .get(AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(bearer_token)
        .map(str::to_string);
    let given = header.or_else(|| {
        (request.uri().path() == QUERY_TOKEN_ROUTE)
            .then(|| query_token(request.uri().query()))
            .flatten()
    });
    match given {
        Some(t) if same(t.as_bytes(), expected.as_bytes()) => Ok(next.run(request).await),
        _ => Err(ApiError::Unauthorized),
    }
}

/// Middleware, when no token is configured: a request a browser made from another site's page
/// (its `Origin` is neither this server nor one of `[api] cors_origins`) is refused, so a web
/// page cannot fly the drone through a tokenless loopback API. Requests without `Origin`
/// (curl, scripts, the CLI) pass. Before that, a request addressed to any `Host` but a loopback
/// name or address is refused: a page whose own name was rebound to 127.0.0.1 (DNS
/// rebinding) sends its own name as both `Host` and `Origin`, which then look alike. A tokenless
/// API only ever listens on loopback (`check_listen`), so the listen address is one of those.
pub async fn this_site_only_without_token(
    State(state): State<ApiState>,
    request: Request,
    next: Next,
) -> Result<Response, ApiError> {
    if state.token.is_some() {
        return Ok(next.run(request).await);
    }
    let headers = request.headers();
    let host = headers
        .get(HOST)
        .map(|v| v.to_str().unwrap_or("(not text)"));
    if let Some(h) = host.filter(|h| !loopback_host(h)) {
        return Err(ApiError::ForeignHost(h.chars().take(100).collect()));
    }
    let Some(origin) = headers.get(ORIGIN).and_then(|v| v.to_str().ok()) else {
        return Ok(next.run(request).await);
    };
    if same_site(origin, host) || state.cors_origins.iter().any(|o| o == origin) {
        return Ok(next.run(request).await);
    }
    Err(ApiError::ForeignOrigin(origin.to_string()))
}

/// Whether a `Host` header (`name`, `name:port`, `[v6]:port`) names this machine's loopback:
/// `localhost` or a loopback address, never a name that DNS could point anywhere.
fn loopback_host(host: &str) -> bool {
    let name = match host.strip_prefix('[') {
        Some(rest) => match rest.split_once(']') {
            Some((ip, "")) => ip,
            Some((ip, port)) if port.strip_prefix(':').is_some_and(is_port) => ip,
            _ => return false,
        },
        None => match host.split_once(':') {
            Some((name, port)) if is_port(port) => name,
            Some(_) => return false,
            None => host,
        },
    };
    let name = name.strip_suffix('.').unwrap_or(name);
    name.eq_ignore_ascii_case("localhost")
        || name.parse::<IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

/// A port number as written after the colon: 1 to 5 digits.
fn is_port(digits: &str) -> bool {
    (1..=5).contains(&digits.len()) && digits.bytes().all(|b| b.is_ascii_digit())
}

/// Whether `origin` (`http://host:port`) is the server the request was sent to (`Host`).
fn same_site(origin: &str, host: Option<&str>) -> bool {
    let authority = origin
        .strip_prefix("http://")
        .or_else(|| origin.strip_prefix("https://"));
    matches!((authority, host), (Some(a), Some(h)) if a.eq_ignore_ascii_case(h))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn environment_wins_then_config_then_file() {
        let mut api = ApiSection::default();
        assert_eq!(resolve_token(None, &api), Ok(None));
        api.token = Some("cfg".into());
        assert_eq!(
            resolve_token(Some("env".into()), &api),
            Ok(Some("env".into()))
        );
        assert_eq!(resolve_token(None, &api), Ok(Some("cfg".into())));
        assert_eq!(
            resolve_token(Some(" ".into()), &api),
            Err(AuthError::EmptyToken)
        );
    }

    #[test]
    fn open_api_only_on_loopback() {
        let lo: SocketAddr = "127.0.0.1:8080".parse().unwrap();
        let any: SocketAddr = "0.0.0.0:8080".parse().unwrap();
        assert!(check_listen(lo, None).is_ok());
        assert!(check_listen(any, None).is_err());
        assert!(check_listen(any, Some("t")).is_ok());
    }

    /// Issue 29, item 9: a page on `rebind.attacker.example`, its name rebound to 127.0.0.1,
    /// sends that name as `Host` (and as `Origin`, which then matches it).
    #[test]
    fn only_loopback_names_and_addresses_are_this_machines_host() {
        for ok in [
            "127.0.0.1:8080",
            "127.0.0.1",
            "127.8.9.10:80",
            "localhost:8080",
            "LOCALHOST",
            "localhost.:8080",
            "[::1]:8080",
            "[::1]",
        ] {
            assert!(loopback_host(ok), "{ok}");
        }
        for refused in [
            "rebind.attacker.example:8080",
            "rebind.attacker.example",
            "localhost.attacker.example:8080",
            "127.0.0.1.nip.io:8080",
            "10.0.0.5:8080",
            "0.0.0.0:8080",
            "[::2]:8080",
            "[::1]junk",
            "[::1]8080",
            "localhost:80:80",
            "localhost:http",
            "",
        ] {
            assert!(!loopback_host(refused), "{refused}");
        }
    }

    #[test]
    fn token_from_query_and_constant_time_compare() {
        assert_eq!(query_token(Some("a=1&token=xyz")).as_deref(), Some("xyz"));
        // What URLSearchParams makes of a base64 token.
        assert_eq!(
            query_token(Some("token=ab%2Bc%2Fd%3D%3D")).as_deref(),
            Some("ab+c/d==")
        );
        assert_eq!(bearer_token("bearer abc"), Some("abc"));
        assert_eq!(bearer_token("BEARER  abc "), Some("abc"));
        assert_eq!(bearer_token("Basic abc"), None);
        assert!(same_site("http://127.0.0.1:8080", Some("127.0.0.1:8080")));
        assert!(!same_site("http://evil.example", Some("127.0.0.1:8080")));
        assert!(!same_site("null", Some("127.0.0.1:8080")));
        assert!(same(b"abc", b"abc"));
        assert!(!same(b"abc", b"abd"));
        assert!(!same(b"abc", b"ab"));
    }
}
