//! The line protocol between an integration test and the `iw-peer` process (agent `b` on its
//! own UDP socket, all four layers on, echoing every message it accepts back to `a`).
//!
//! ```text
//! peer -> test   READY <udp socket address> <b's Ed25519 public key, hex>
//! test -> peer   PEER <a's public key, hex> <address to send to (the proxy)>
//! test -> peer   REPORT
//! peer -> test   REPORT <Report as key=value pairs>
//! ```

/// What the peer accepted.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Report {
    /// Messages delivered to agent `b`.
    pub delivered: u64,
    /// Distinct message numbers among them.
    pub unique: u64,
    /// Numbers delivered more than once.
    pub duplicates: u64,
    /// Deliveries that were not `a`'s numbered messages (forged or altered).
    pub foreign: u64,
    /// The peer stack's rejection counters, as printed by `Counters`.
    pub counters: String,
}

impl Report {
    /// The `REPORT ...` line.
    pub fn to_line(&self) -> String {
        format!(
            "REPORT delivered={} unique={} duplicates={} foreign={} counters={}",
            self.delivered,
            self.unique,
            self.duplicates,
            self.foreign,
            self.counters.replace(' ', ",")
        )
    }

    /// Parses a `REPORT ...` line.
    pub fn parse(line: &str) -> Option<Report> {
        let mut r = Report::default();
        let rest = line.trim().strip_prefix("REPORT ")?;
        for pair in rest.split(' ') {
            let (k, v) = pair.split_once('=')?;
            match k {
                "delivered" => r.delivered = v.parse().ok()?,
                "unique" => r.unique = v.parse().ok()?,
                "duplicates" => r.duplicates = v.parse().ok()?,
                "foreign" => r.foreign = v.parse().ok()?,
                "counters" => r.counters = v.replace(',', " "),
                _ => return None,
            }
        }
        Some(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn report_round_trips() {
        let r = Report {
            delivered: 5,
            unique: 5,
            duplicates: 0,
            foreign: 0,
            counters: "duplicate=3 bad_tag=1".into(),
        };
        assert_eq!(Report::parse(&r.to_line()), Some(r));
        assert_eq!(Report::parse("REPORT bogus"), None);
    }
}
