//! The in-process [`FrameTransport`]: endpoints of one [`InProcNetwork`] exchange frames over
//! channels, for containers in one process and for tests.

use std::collections::HashMap;
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, TryRecvError};
use std::sync::{Arc, Mutex, PoisonError, RwLock};
use std::time::Duration;

use crate::transport::{FrameTransport, PeerAddr, TransportError};

type Frame = (PeerAddr, Vec<u8>);

/// A set of in-process endpoints that can reach one another by name.
#[derive(Debug, Clone, Default)]
pub struct InProcNetwork {
    nodes: Arc<RwLock<HashMap<PeerAddr, Sender<Frame>>>>,
}

impl InProcNetwork {
    /// Largest frame an in-process endpoint carries: 1 MiB (no datagram limit applies, but the
    /// bound keeps one bad sender from exhausting memory).
    pub const MAX_FRAME_LEN: usize = 1 << 20;

    /// An empty network.
    pub fn new() -> InProcNetwork {
        InProcNetwork::default()
    }

    /// Opens the endpoint `name`; fails if that name is taken.
    pub fn endpoint(&self, name: &str) -> Result<InProcTransport, TransportError> {
        let addr = PeerAddr(name.to_string());
        let (tx, rx) = std::sync::mpsc::channel();
        let mut nodes = self.nodes.write().unwrap_or_else(PoisonError::into_inner);
        if nodes.contains_key(&addr) {
            return Err(TransportError::BadAddress {
                addr: name.to_string(),
                reason: "endpoint name already in use".into(),
            });
        }
        nodes.insert(addr.clone(), tx);
        Ok(InProcTransport {
            addr,
            net: self.clone(),
            rx: Mutex::new(rx),
        })
    }
}

/// One endpoint of an [`InProcNetwork`]; closing it (drop) frees its name.
#[derive(Debug)]
pub struct InProcTransport {
    addr: PeerAddr,
    net: InProcNetwork,
    rx: Mutex<Receiver<Frame>>,
}

impl FrameTransport for InProcTransport {
    fn local_addr(&self) -> &PeerAddr {
        &self.addr
    }
    fn max_frame_len(&self) -> usize {
        InProcNetwork::MAX_FRAME_LEN
    }
    fn send(&self, to: &PeerAddr, frame: &[u8]) -> Result<(), TransportError> {
        if frame.len() > InProcNetwork::MAX_FRAME_LEN {
            return Err(TransportError::FrameTooLarge {
                len: frame.len(),
                max: InProcNetwork::MAX_FRAME_LEN,
            });
        }
        let nodes = self
            .net
            .nodes
            .read()
            .unwrap_or_else(PoisonError::into_inner);
        let tx = nodes.get(to).ok_or_else(|| TransportError::BadAddress {
            addr: to.0.clone(),
            reason: "no such in-process endpoint".into(),
        })?;
        tx.send((self.addr.clone(), frame.to_vec()))
            .map_err(|_| TransportError::Closed)
    }
    fn recv_timeout(&self, timeout: Duration) -> Result<Option<Frame>, TransportError> {
        let rx = self.rx.lock().unwrap_or_else(PoisonError::into_inner);
        // A zero timeout is a poll (the pump's): `recv_timeout` would read the clock for it.
        if timeout.is_zero() {
            return match rx.try_recv() {
                Ok(f) => Ok(Some(f)),
                Err(TryRecvError::Empty) => Ok(None),
                Err(TryRecvError::Disconnected) => Err(TransportError::Closed),
            };
        }
        match rx.recv_timeout(timeout) {
            Ok(f) => Ok(Some(f)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(TransportError::Closed),
        }
    }
}

impl Drop for InProcTransport {
    fn drop(&mut self) {
        self.net
            .nodes
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(&self.addr);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_exchange_frames() {
        let net = InProcNetwork::new();
        let a = net.endpoint("a").unwrap();
        let b = net.endpoint("b").unwrap();
        assert!(net.endpoint("a").is_err());
        a.send(b.local_addr(), b"hi").unwrap();
        let (from, frame) = b.recv_timeout(Duration::from_secs(1)).unwrap().unwrap();
        assert_eq!((from.0.as_str(), frame.as_slice()), ("a", &b"hi"[..]));
        assert!(b.recv_timeout(Duration::from_millis(1)).unwrap().is_none());
        assert!(a.send(&PeerAddr("nobody".into()), b"x").is_err());
        drop(b);
        assert!(a.send(&PeerAddr("b".into()), b"x").is_err());
    }
}
