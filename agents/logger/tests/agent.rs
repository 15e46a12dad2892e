//! The logger agent alone on an in-process bus with a mock clock: copies and carbon copies are
//! stored, queries answered, and every message survives a crash with a torn tail.

use std::io::Write;
use std::sync::Arc;
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::gateway::{GatewayHandle, gateway};
use iw_agent::{AgentHost, TypedContent};
use iw_bus::{Bus, BusConfig, Clock, InProcNetwork, MockController, Stack, Time};
use iw_logger::agent::{LOG_LANGUAGE, LOG_ONTOLOGY, LoggerAgent, LoggerConfig, copy_for_logger};
use iw_logger::{LoggedMessage, Query, SyncPolicy};

fn host(config: &LoggerConfig, name: &str) -> (AgentHost, MockController, GatewayHandle) {
    let network = InProcNetwork::new();
    let (clock, controller) = Clock::mock(Time::from_ns(1_000_000_000));
    let bus = Bus::start(
        Stack::new(),
        Arc::new(network.endpoint(name).unwrap()),
        clock,
        BusConfig::default(),
    )
    .unwrap();
    let mut host = AgentHost::new(Arc::new(bus));
    host.add(
        AgentId::new("logger"),
        Box::new(LoggerAgent::open(config).unwrap()),
    )
    .unwrap();
    let (agent, probe) = gateway(Duration::from_millis(1));
    host.add(AgentId::new("probe"), Box::new(agent)).unwrap();
    (host, controller, probe)
}

fn run(host: &mut AgentHost, clock: &MockController, steps: usize) {
    for _ in 0..steps {
        host.step(clock.now());
        clock.advance(Duration::from_millis(10));
    }
}

fn query(q: &Query) -> AclMessage {
    q.fill_into(
        AclMessage::new(Performative::Request)
            .with_receiver(AgentId::new("logger"))
            .with_conversation_id("q"),
    )
}

#[test]
fn every_message_survives_a_crash_and_queries_find_them() {
    let dir = tempfile::tempdir().unwrap();
    let config = LoggerConfig {
        path: dir.path().join("bus.log"),
        policy: SyncPolicy::Always,
        sync_period: Duration::from_millis(100),
    };
    let (mut host, clock, probe) = host(&config, "c1");
    for i in 0..50u64 {
        let original = AclMessage::new(if i % 2 == 0 {
            Performative::Request
        } else {
            Performative::Inform
        })
        .with_sender(AgentId::new(format!("chair{}", i % 3)))
        .with_receiver(AgentId::new("door"))
        .with_conversation_id(format!("c{i}"))
        .with_content(format!("((open-door \"d{i}\"))"));
        probe.send(copy_for_logger(
            &original,
            &AgentId::new("logger"),
            1_000 + i,
        ));
    }
    // A carbon copy: the logger is simply one more receiver.
    probe.send(
        AclMessage::new(Performative::Cfp)
            .with_receiver(AgentId::new("logger"))
            .with_content("cc"),
    );
    run(&mut host, &clock, 5);
    assert!(probe.take_send_errors().is_empty());
    // Crash: no take-down, and a half-written record at the end of the file.
    std::mem::forget(host);
    std::fs::OpenOptions::new()
        .append(true)
        .open(&config.path)
        .unwrap()
        .write_all(&[7, 0, 0, 0, 1, 2])
        .unwrap();

    let (mut host, clock, probe) = self::host(&config, "c2");
    probe.send(query(&Query::default()));
    probe.send(query(&Query {
        sender: Some("chair1".into()),
        performative: Some("INFORM".into()),
        ..Query::default()
    }));
    probe.send(
        AclMessage::new(Performative::Request)
            .with_receiver(AgentId::new("logger"))
            .with_ontology(LOG_ONTOLOGY)
            .with_content("not json"),
    );
    run(&mut host, &clock, 3);
    assert!(probe.take_send_errors().is_empty());
    let inbox = probe.take_received();
    let answers: Vec<_> = inbox.iter().map(|m| m.performative).collect();
    assert_eq!(
        answers,
        [
            Performative::Inform,
            Performative::Inform,
            Performative::NotUnderstood
        ]
    );
    for answer in &inbox[..2] {
        assert_eq!(
            (
                answer.language.as_deref(),
                answer.ontology.as_deref(),
                answer.protocol.as_deref()
            ),
            (Some(LOG_LANGUAGE), Some(LOG_ONTOLOGY), Some("fipa-request")),
            "a typed answer in the query's conversation"
        );
    }
    let all: Vec<LoggedMessage> = serde_json::from_str(inbox[0].content_text().unwrap()).unwrap();
    assert_eq!(all.len(), 51, "50 copies and the carbon copy");
    for (i, m) in all.iter().take(50).enumerate() {
        assert_eq!(m.time_ns, 1_000 + i as u64);
        assert_eq!(m.conversation_id.as_deref(), Some(format!("c{i}").as_str()));
        assert_eq!(m.receivers, ["door"]);
    }
    assert_eq!(all[50].performative, "cfp");
    let some: Vec<LoggedMessage> = serde_json::from_str(inbox[1].content_text().unwrap()).unwrap();
    assert!(!some.is_empty());
    assert!(
        some.iter()
            .all(|m| m.sender == "chair1" && m.performative == "inform")
    );
    assert_eq!(
        some.len(),
        all.iter()
            .filter(|m| m.sender == "chair1" && m.performative == "inform")
            .count()
    );
}
