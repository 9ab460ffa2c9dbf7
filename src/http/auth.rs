//! API keys. The key file holds one key per line as `NAME SHA256HEX` (the hash of the
//! key, never the key itself); `millsim api-key NAME` makes a key and its line.
//! Each key's resources and jobs are invisible to the others.

use axum::extract::{Request, State};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};
use subtle::ConstantTimeEq;

use super::problem::ApiError;
use super::{AppState, Owner};

pub struct Auth {
    keys: Vec<(String, [u8; 32])>,
}

#[derive(Debug, thiserror::Error)]
#[error("{file}:{line}: {message}")]
pub struct KeyFileError {
    pub file: String,
    pub line: usize,
    pub message: String,
}

pub fn hash_key(key: &str) -> [u8; 32] {
    Sha256::digest(key.as_bytes()).into()
}

pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

impl Auth {
    /// No keys: every request is served, as owner "".
    pub fn disabled() -> Auth {
        Auth { keys: Vec::new() }
    }

    pub fn enabled(&self) -> bool {
        !self.keys.is_empty()
    }

    pub fn from_key_file(file: &str, text: &str) -> Result<Auth, KeyFileError> {
        let mut keys = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let err = |message: &str| KeyFileError {
                file: file.into(),
                line: i + 1,
                message: message.into(),
            };
            let mut parts = line.split_whitespace();
            let (Some(name), Some(hash), None) = (parts.next(), parts.next(), parts.next()) else {
                return Err(err("expected `NAME SHA256HEX`"));
            };
            if hash.len() != 64 || !hash.bytes().all(|b| b.is_ascii_hexdigit()) {
                return Err(err(
                    "the hash must be 64 hexadecimal digits (the SHA-256 of the key)",
                ));
            }
            let mut h = [0u8; 32];
            for (j, byte) in h.iter_mut().enumerate() {
                *byte = u8::from_str_radix(&hash[2 * j..2 * j + 2], 16)
                    .map_err(|_| err("bad hex digit"))?;
            }
            keys.push((name.to_string(), h));
        }
        if keys.is_empty() {
            return Err(KeyFileError {
                file: file.into(),
                line: 0,
                message: "the file holds no keys".into(),
            });
        }
        Ok(Auth { keys })
    }

    /// The name of the key, comparing hashes in constant time against every entry.
    fn owner_of(&self, presented: &str) -> Option<String> {
        let h = hash_key(presented);
        let mut found = None;
        for (name, stored) in &self.keys {
            if bool::from(stored.ct_eq(&h)) {
                found = Some(name.clone());
            }
        }
        found
    }
}

/// The owner of the key a request presents: `Authorization: Bearer KEY` (the scheme in any
/// case, as RFC 9110 has it) and/or `X-API-Key: KEY`. Two different keys are refused, even
/// when one is valid: a request speaks for one key.
fn presented_owner(auth: &Auth, headers: &axum::http::HeaderMap) -> Option<String> {
    let bearer = match headers.get("authorization") {
        Some(v) => {
            let v = v.to_str().ok()?;
            let (scheme, key) = v.split_once(' ')?;
            if !scheme.eq_ignore_ascii_case("bearer") {
                return None;
            }
            Some(key.trim())
        }
        None => None,
    };
    let header = match headers.get("x-api-key") {
        Some(v) => Some(v.to_str().ok()?.trim()),
        None => None,
    };
    let key = match (bearer, header) {
        (Some(a), Some(b)) if a != b => return None,
        (Some(a), _) => a,
        (None, Some(b)) => b,
        (None, None) => return None,
    };
    auth.owner_of(key)
}

pub async fn require_key(State(state): State<AppState>, mut req: Request, next: Next) -> Response {
    let owner = if state.auth.enabled() {
        match presented_owner(&state.auth, req.headers()) {
            Some(name) => name,
            None => {
                return ApiError::unauthorized(
                    "send a valid API key as `Authorization: Bearer KEY` or `X-API-Key: KEY`",
                )
                .into_response()
            }
        }
    } else {
        String::new()
    };
    req.extensions_mut().insert(Owner(owner));
    next.run(req).await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bearer_scheme_is_case_insensitive_and_conflicting_keys_are_refused() {
        let key = "k-0123456789abcdef";
        let auth = Auth::from_key_file("keys", &format!("mes {}\n", hex(&hash_key(key)))).unwrap();
        let headers = |pairs: &[(&str, &str)]| {
            let mut h = axum::http::HeaderMap::new();
            for (n, v) in pairs {
                h.insert(
                    axum::http::HeaderName::from_bytes(n.as_bytes()).unwrap(),
                    v.parse().unwrap(),
                );
            }
            h
        };
        for scheme in ["Bearer", "bearer", "BEARER"] {
            let h = headers(&[("authorization", &format!("{scheme} {key}"))]);
            assert_eq!(
                presented_owner(&auth, &h).as_deref(),
                Some("mes"),
                "{scheme}"
            );
        }
        assert_eq!(
            presented_owner(&auth, &headers(&[("x-api-key", key)])).as_deref(),
            Some("mes")
        );
        let both = headers(&[
            ("authorization", &format!("Bearer {key}")),
            ("x-api-key", key),
        ]);
        assert_eq!(presented_owner(&auth, &both).as_deref(), Some("mes"));
        // A valid bearer with another X-API-Key: refused (before, the bearer won).
        let conflict = headers(&[
            ("authorization", &format!("Bearer {key}")),
            ("x-api-key", "wrong"),
        ]);
        assert_eq!(presented_owner(&auth, &conflict), None);
        let basic = headers(&[("authorization", &format!("Basic {key}"))]);
        assert_eq!(presented_owner(&auth, &basic), None);
    }

    #[test]
    fn key_file_maps_keys_to_names() {
        let line = format!(
            "cam {}\n# comment\nmes {}\n",
            hex(&hash_key("k1")),
            hex(&hash_key("k2"))
        );
        let auth = Auth::from_key_file("keys", &line).unwrap();
        assert_eq!(auth.owner_of("k1").as_deref(), Some("cam"));
        assert_eq!(auth.owner_of("k2").as_deref(), Some("mes"));
        assert_eq!(auth.owner_of("k3"), None);
        let err = Auth::from_key_file("keys", "cam notahash\n").err().unwrap();
        assert_eq!((err.line, err.file.as_str()), (1, "keys"));
    }
}
