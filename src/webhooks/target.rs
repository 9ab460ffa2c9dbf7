//! Where a webhook may post: an `http://` URL whose host is public, unless the server runs
//! with `--webhook-allow-private` (a plant network, tests). The URL is checked when the
//! webhook is registered, and the addresses its host resolves to at every delivery, so a
//! name that later points inside the network is refused then too.

use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};
use std::time::Duration;

use reqwest::Url;

/// Longest URL accepted.
const MAX_URL: usize = 2048;

/// How long resolving a target's host may take.
const RESOLVE_TIMEOUT: Duration = Duration::from_secs(5);

/// The URL as registered, or why not (the message names what is wrong).
pub fn check_url(url: &str, allow_private: bool) -> Result<Url, String> {
    if url.len() > MAX_URL {
        return Err(format!("at most {MAX_URL} characters"));
    }
    let parsed = Url::parse(url).map_err(|e| format!("not a URL: {e}"))?;
    match parsed.scheme() {
        "http" => {}
        "https" => {
            return Err(
                "https targets are not supported by this build (it has no TLS stack); use http:// inside the network or a TLS-terminating relay"
                    .into(),
            )
        }
        other => return Err(format!("scheme `{other}` is not http")),
    }
    let host = parsed
        .host_str()
        .filter(|h| !h.is_empty())
        .ok_or("no host")?;
    if !allow_private {
        let literal = host
            .trim_start_matches('[')
            .trim_end_matches(']')
            .parse::<IpAddr>()
            .ok();
        if is_local_name(host) || literal.is_some_and(is_private) {
            return Err(format!(
                "`{host}` is a private or loopback address; the server needs --webhook-allow-private to post there"
            ));
        }
    }
    Ok(parsed)
}

/// Names that mean this host whatever DNS says: `localhost` and its subdomains (RFC 6761),
/// the names Debian's /etc/hosts gives loopback, in any case and with trailing dots (the
/// absolute `localhost.` is the same name). Registration and delivery both ask this (through
/// `check_url`), so a name is refused when registered, not first at delivery.
pub fn is_local_name(host: &str) -> bool {
    let name = host.trim_end_matches('.').to_ascii_lowercase();
    name == "localhost"
        || name.ends_with(".localhost")
        || matches!(
            name.as_str(),
            "localhost.localdomain" | "ip6-localhost" | "ip6-loopback"
        )
}

/// The addresses to connect to for `url`: all of its host's, every one public unless
/// private targets are allowed.
pub async fn resolve(url: &Url, allow_private: bool) -> Result<Vec<SocketAddr>, String> {
    let host = url.host_str().ok_or("no host")?;
    let port = url.port_or_known_default().ok_or("no port")?;
    let bare = host.trim_start_matches('[').trim_end_matches(']');
    let addrs: Vec<SocketAddr> = match bare.parse::<IpAddr>() {
        Ok(ip) => vec![SocketAddr::new(ip, port)],
        Err(_) => tokio::time::timeout(RESOLVE_TIMEOUT, tokio::net::lookup_host((bare, port)))
            .await
            .map_err(|_| format!("resolving `{host}` took over {RESOLVE_TIMEOUT:?}"))?
            .map_err(|e| format!("resolving `{host}`: {e}"))?
            .collect(),
    };
    if addrs.is_empty() {
        return Err(format!("`{host}` resolves to no address"));
    }
    if !allow_private {
        if let Some(a) = addrs.iter().find(|a| is_private(a.ip())) {
            return Err(format!(
                "`{host}` resolves to {}, a private or loopback address (the server needs --webhook-allow-private)",
                a.ip()
            ));
        }
    }
    Ok(addrs)
}

/// Loopback, private, link-local, shared, documentation, multicast and other addresses
/// that are not a public host's.
pub fn is_private(ip: IpAddr) -> bool {
    match ip {
        IpAddr::V4(v4) => private_v4(v4),
        IpAddr::V6(v6) => match v6.to_ipv4_mapped() {
            Some(v4) => private_v4(v4),
            None => private_v6(v6),
        },
    }
}

fn private_v4(ip: Ipv4Addr) -> bool {
    let [a, b, c, _] = ip.octets();
    ip.is_private()
        || ip.is_loopback()
        || ip.is_link_local()
        || ip.is_unspecified()
        || ip.is_broadcast()
        || ip.is_documentation()
        || ip.is_multicast()
        || a == 0
        || (a == 100 && (64..128).contains(&b)) // shared address space (carrier NAT)
        || (a == 192 && b == 0 && c == 0) // IETF protocol assignments
        || (a == 198 && (18..20).contains(&b)) // benchmarking
        || a >= 240 // reserved
}

fn private_v6(ip: Ipv6Addr) -> bool {
    let first = ip.segments()[0];
    ip.is_loopback()
        || ip.is_unspecified()
        || ip.is_multicast()
        || (first & 0xfe00) == 0xfc00 // unique local
        || (first & 0xffc0) == 0xfe80 // link local
        || (first == 0x2001 && ip.segments()[1] == 0x0db8) // documentation
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn private_and_loopback_targets_need_the_option() {
        for url in [
            "http://127.0.0.1:9000/hook",
            "http://localhost/hook",
            "http://10.1.2.3/hook",
            "http://192.168.0.5:8080/",
            "http://169.254.169.254/latest/meta-data",
            "http://[::1]:9000/",
            "http://[fd00::1]/",
            "http://[::ffff:10.0.0.1]/",
            "http://100.64.0.1/",
        ] {
            assert!(check_url(url, false).is_err(), "{url}");
            assert!(check_url(url, true).is_ok(), "{url}");
        }
        assert!(check_url("http://93.184.215.14/hook", false).is_ok());
        assert!(check_url("http://mes.example.com/hook", false).is_ok());
    }

    #[test]
    fn localhost_spelled_any_way_is_local() {
        for url in [
            "http://localhost./",
            "http://LOCALHOST./hook",
            "http://LocalHost/",
            "http://localhost../",
            "http://mes.localhost./",
            "http://localhost.localdomain/",
            "http://LOCALHOST.LOCALDOMAIN./",
            "http://ip6-localhost:9000/",
            "http://127.0.0.1./",
        ] {
            let e = check_url(url, false).unwrap_err();
            assert!(e.contains("private or loopback"), "{url}: {e}");
            assert!(check_url(url, true).is_ok(), "{url}");
        }
        assert!(!is_local_name("localhost.example.com"));
        assert!(!is_local_name("mylocalhost"));
    }

    #[test]
    fn only_http_urls_with_a_host() {
        assert!(check_url("ftp://example.com/", true).is_err());
        assert!(check_url("https://example.com/", true)
            .unwrap_err()
            .contains("TLS"));
        assert!(check_url("not a url", true).is_err());
        assert!(check_url(&format!("http://example.com/{}", "a".repeat(3000)), true).is_err());
    }

    #[tokio::test]
    async fn a_name_resolving_to_loopback_is_refused_at_delivery() {
        let url = Url::parse("http://localhost:9/").unwrap();
        let e = resolve(&url, false).await.unwrap_err();
        assert!(e.contains("private or loopback"), "{e}");
        assert!(!resolve(&url, true).await.unwrap().is_empty());
    }
}
