//! The address of the live view, `HOST:PORT`.

use std::net::{SocketAddr, ToSocketAddrs};

use super::error::LiveError;

/// Where the live view listens unless told otherwise (Foxglove's default).
pub const DEFAULT_LIVE_ADDR: &str = "127.0.0.1:8765";

/// Resolves `HOST:PORT` (`127.0.0.1:8765`, `0.0.0.0:0`, `localhost:8765`,
/// `[::1]:8765`) to its first socket address. Port 0 asks for a free port.
pub fn resolve_addr(addr: &str) -> Result<SocketAddr, LiveError> {
    let bad = |detail: String| LiveError::Address { addr: addr.to_string(), detail };
    if addr.rsplit_once(':').is_none_or(|(host, port)| host.is_empty() || port.parse::<u16>().is_err()) {
        return Err(bad("expected HOST:PORT, for example 127.0.0.1:8765".into()));
    }
    let mut found = addr.to_socket_addrs().map_err(|e| bad(format!("cannot resolve it ({e})")))?;
    found.next().ok_or_else(|| bad("it resolves to no address".into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_resolve_or_say_what_is_wrong() {
        assert_eq!(resolve_addr("127.0.0.1:8765").expect("ip").port(), 8765);
        assert_eq!(resolve_addr("[::1]:0").expect("ipv6").port(), 0);
        for bad in ["8765", "127.0.0.1", ":8765", "127.0.0.1:port", "127.0.0.1:70000"] {
            let e = resolve_addr(bad).expect_err(bad).to_string();
            assert!(e.contains("HOST:PORT"), "{bad}: {e}");
        }
    }
}
