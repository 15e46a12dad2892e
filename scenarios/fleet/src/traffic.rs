//! What the containers' taps see: every message counted (and copied to the logger), and each
//! chair's last route read off its cognitive agent's requests.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use iw_acl::AclMessage;
use iw_agent::AgentHost;
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{WheelchairAction, WheelchairContent};
use iw_wiring as compose;
use iw_wiring::SERVICES;

/// What the taps of all containers see: the traffic count and each chair's last route.
#[derive(Default)]
pub(crate) struct Traffic {
    pub(crate) sent: AtomicU64,
    pub(crate) paths: Mutex<BTreeMap<String, Vec<[f64; 2]>>>,
}

impl Traffic {
    fn saw(&self, message: &AclMessage) {
        self.sent.fetch_add(1, Ordering::AcqRel);
        let from_cognitive = message
            .sender
            .as_ref()
            .and_then(|s| s.name.strip_prefix("cognitive@"));
        let (
            Some(chair),
            Ok(WheelchairContent::Request {
                action: WheelchairAction::Sequence { steps },
                ..
            }),
        ) = (from_cognitive, WheelchairContent::from_message(message))
        else {
            return;
        };
        let points = steps
            .iter()
            .filter_map(|s| match s {
                WheelchairAction::GotoXy { x_m, y_m } => Some([*x_m, *y_m]),
                _ => None,
            })
            .collect();
        self.paths
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(chair.to_string(), points);
    }
}

pub(crate) fn tap_into(host: &mut AgentHost, traffic: &Arc<Traffic>) {
    let traffic = traffic.clone();
    let tap = compose::log_tap(
        host.bus().clone(),
        compose::agent_id("logger", SERVICES),
        move |m| traffic.saw(m),
    );
    host.set_tap(tap);
}
