//! [`ConnectionSlots`]: connections held at once, in total and per source address, for every
//! listener that takes connections from outside (the TCP transport, the HTTP MTP): a flood is
//! closed at accept, and one host cannot take every slot.

use std::collections::HashMap;
use std::net::IpAddr;
use std::sync::{Arc, Mutex, PoisonError};

/// The connections held under a total cap and a per-source cap.
#[derive(Debug)]
pub struct ConnectionSlots {
    max_total: usize,
    max_per_source: usize,
    held: Mutex<(usize, HashMap<IpAddr, usize>)>,
}

/// One connection's hold on [`ConnectionSlots`], given back when dropped.
#[derive(Debug)]
pub struct ConnectionSlot {
    slots: Arc<ConnectionSlots>,
    source: IpAddr,
}

impl ConnectionSlots {
    /// At most `max_total` connections at once, `max_per_source` of them from one address.
    pub fn new(max_total: usize, max_per_source: usize) -> Arc<Self> {
        Arc::new(Self {
            max_total,
            max_per_source,
            held: Mutex::new((0, HashMap::new())),
        })
    }

    /// A slot for a connection from `source` (an IPv4-mapped IPv6 address counts as its IPv4
    /// address), or why there is none.
    pub fn take(self: &Arc<Self>, source: IpAddr) -> Result<ConnectionSlot, &'static str> {
        let source = source.to_canonical();
        let mut held = self.held.lock().unwrap_or_else(PoisonError::into_inner);
        let (total, per_source) = &mut *held;
        if *total >= self.max_total {
            return Err("connection cap reached");
        }
        let of_source = per_source.entry(source).or_default();
        if *of_source >= self.max_per_source {
            return Err("source over its connection cap");
        }
        *of_source += 1;
        *total += 1;
        Ok(ConnectionSlot {
            slots: Arc::clone(self),
            source,
        })
    }
}

impl Drop for ConnectionSlot {
    fn drop(&mut self) {
        let mut held = self
            .slots
            .held
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let (total, per_source) = &mut *held;
        *total -= 1;
        if let Some(n) = per_source.get_mut(&self.source) {
            *n -= 1;
            if *n == 0 {
                per_source.remove(&self.source);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_are_capped_in_total_and_per_source_and_given_back() {
        let slots = ConnectionSlots::new(3, 2);
        let a: IpAddr = "10.0.0.1".parse().unwrap();
        let b: IpAddr = "10.0.0.2".parse().unwrap();
        let mapped: IpAddr = "::ffff:10.0.0.1".parse().unwrap();
        let first = slots.take(a).unwrap();
        let _second = slots.take(mapped).unwrap();
        assert_eq!(slots.take(a).unwrap_err(), "source over its connection cap");
        let _third = slots.take(b).unwrap();
        assert_eq!(slots.take(b).unwrap_err(), "connection cap reached");
        drop(first);
        let _again = slots.take(a).unwrap();
    }
}
