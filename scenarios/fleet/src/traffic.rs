//! What the containers' taps see: every message counted (and copied to the logger), each
//! chair's last route read off its cognitive agent's requests, and the last pose its perception
//! agent published.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use iw_acl::AclMessage;
use iw_agent::AgentHost;
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{Fact, Pose, WheelchairAction, WheelchairContent};
use iw_wiring as compose;
use iw_wiring::SERVICES;

/// What the taps of all containers see: the traffic count, each chair's last route and the
/// last pose its perception agent published.
#[derive(Default)]
pub(crate) struct Traffic {
    pub(crate) sent: AtomicU64,
    pub(crate) paths: Mutex<BTreeMap<String, Vec<[f64; 2]>>>,
    pub(crate) estimates: Mutex<BTreeMap<String, Pose>>,
}

impl Traffic {
    fn saw(&self, message: &AclMessage) {
        self.sent.fetch_add(1, Ordering::AcqRel);
        let sender = message.sender.as_ref().map(|s| s.name.as_str());
        if let Some(chair) = sender.and_then(|s| s.strip_prefix("perception@")) {
            if let Ok(WheelchairContent::Inform(Fact::AtPose { pose, .. })) =
                WheelchairContent::from_message(message)
            {
                self.estimates
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .insert(chair.to_string(), pose);
            }
            return;
        }
        let (
            Some(chair),
            Ok(WheelchairContent::Request {
                action: WheelchairAction::Sequence { steps },
                ..
            }),
        ) = (
            sender.and_then(|s| s.strip_prefix("cognitive@")),
            WheelchairContent::from_message(message),
        )
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
