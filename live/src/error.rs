//! Errors of the live view.

use std::net::SocketAddr;
use std::path::PathBuf;

/// What can go wrong serving the live view.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LiveError {
    /// The address is not `HOST:PORT`, or the host does not resolve.
    #[error("live view address `{addr}`: {detail}")]
    Address {
        /// The address as given.
        addr: String,
        /// What is wrong with it.
        detail: String,
    },
    /// The server could not listen there (port in use, address not of this machine).
    #[error("cannot serve the live view on {addr}: {source}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
    /// The Foxglove SDK refused something else.
    #[error("live view: {0}")]
    Server(#[from] foxglove::FoxgloveError),
    /// A thread could not be started.
    #[error("live view: cannot start its thread: {0}")]
    Thread(std::io::Error),
    /// A session to play cannot be read.
    #[error("{path}: {detail}")]
    Session {
        /// The session file.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
    /// A viewer probe failed (connection, handshake, protocol).
    #[error("viewer probe: {0}")]
    Probe(String),
}

impl LiveError {
    /// The error of starting a server on `addr`: the address refused, or
    /// anything else the SDK reports.
    pub fn starting(addr: SocketAddr, e: foxglove::FoxgloveError) -> LiveError {
        match e {
            foxglove::FoxgloveError::Bind(source) => LiveError::Bind { addr, source },
            other => LiveError::Server(other),
        }
    }
}
