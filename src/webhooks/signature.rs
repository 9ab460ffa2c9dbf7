//! The `Millsim-Signature` header: `t=<unix seconds>,v1=<hex HMAC-SHA256(secret, "<t>.<body>")>`.
//! The time is inside what is signed, so a receiver that refuses old times refuses replays.

use hmac::{Hmac, Mac};
use sha2::Sha256;

/// The header value for `body` sent at `unix_seconds`.
pub fn header(secret: &str, unix_seconds: i64, body: &str) -> String {
    let signed = format!("{unix_seconds}.{body}");
    format!(
        "t={unix_seconds},v1={}",
        hmac_sha256_hex(secret, signed.as_bytes())
    )
}

fn hmac_sha256_hex(key: &str, data: &[u8]) -> String {
    // HMAC takes keys of any length: new_from_slice cannot fail for it.
    let mut mac = Hmac::<Sha256>::new_from_slice(key.as_bytes()).expect("any key length");
    mac.update(data);
    mac.finalize()
        .into_bytes()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// A new webhook secret: 256 random bits (two v4 UUIDs from the OS generator), prefixed
/// so a leaked one is recognizable.
pub fn new_secret() -> String {
    format!(
        "whsec_{}{}",
        uuid::Uuid::new_v4().simple(),
        uuid::Uuid::new_v4().simple()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hmac_matches_rfc_4231_test_case_2() {
        assert_eq!(
            hmac_sha256_hex("Jefe", b"what do ya want for nothing?"),
            "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843"
        );
    }

    #[test]
    fn the_header_signs_time_dot_body() {
        let h = header("whsec_x", 1_764_000_000, r#"{"a":1}"#);
        let expected = hmac_sha256_hex("whsec_x", br#"1764000000.{"a":1}"#);
        assert_eq!(h, format!("t=1764000000,v1={expected}"));
        // Another time or body gives another signature.
        assert_ne!(h, header("whsec_x", 1_764_000_001, r#"{"a":1}"#));
        assert_ne!(h, header("whsec_x", 1_764_000_000, r#"{"a":2}"#));
    }

    #[test]
    fn secrets_are_long_and_different() {
        let (a, b) = (new_secret(), new_secret());
        assert_eq!(a.len(), 6 + 64);
        assert_ne!(a, b);
    }
}
