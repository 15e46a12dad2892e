//! The perception agent alone on an in-process bus with a mock clock.

use std::sync::Arc;
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::AgentHost;
use iw_agent::gateway::{GatewayHandle, gateway};
use iw_body::layout::Footprint;
use iw_body::{Body, BodyError, SensorFrame, WheelSpeeds};
use iw_bus::{MockController, Time};
use iw_localization::{LocalizationMap, Localizer, LocalizerConfig, SonarGeometry};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{Fact, SensorReading, SensorUse, WheelchairContent};
use iw_perception::{PerceptionAgent, PerceptionConfig};
use iw_vo::{AccelerationSlip, Pose2};

/// Both wheels advance 100 ticks per read; sonar 0 sees a wall at 1.2 m; every 7th read fails.
struct Rolling {
    reads: i64,
}

impl Body for Rolling {
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        self.reads += 1;
        if self.reads % 7 == 0 {
            return Err(BodyError::Virtual {
                reason: "dropped frame".into(),
            });
        }
        let mut frame = SensorFrame::empty(self.reads as u64 * 50_000_000);
        frame.left_ticks = self.reads * 100;
        frame.right_ticks = self.reads * 100;
        frame.sonar_m[0] = Some(1.2);
        Ok(frame)
    }
    fn command(&mut self, _: WheelSpeeds) -> Result<(), BodyError> {
        Ok(())
    }
}

#[test]
fn subscribers_get_poses_with_growing_covariance_until_they_cancel() {
    let config = PerceptionConfig::prototype(AgentId::new("chair1"), Pose2::new(1.0, 2.0, 0.0));
    let agent = PerceptionAgent::new(config, Box::new(Rolling { reads: 0 }), None).unwrap();
    let (mut host, controller, probe) = beside_a_probe(agent);
    let subscribe = |content: &str| {
        AclMessage::new(Performative::Subscribe)
            .with_receiver(AgentId::new("perception"))
            .with_protocol("fipa-subscribe")
            .with_conversation_id("s1")
            .with_content(content)
    };
    probe.send(subscribe(
        "((at-pose ?agent ?pose) (sensor-reading ?agent ?reading))",
    ));
    let mut run = |ms: u64| {
        for _ in 0..ms / 10 {
            host.step(controller.now());
            controller.advance(Duration::from_millis(10));
        }
    };
    run(2000);
    let poses: Vec<_> = {
        assert!(probe.take_send_errors().is_empty());
        let inbox = probe.take_received();
        assert_eq!(inbox[0].performative, Performative::Agree);
        let mut sonar_seen = false;
        let mut poses = Vec::new();
        for m in inbox.iter().skip(1) {
            assert_eq!(m.conversation_id.as_deref(), Some("s1"));
            match WheelchairContent::from_message(m).unwrap() {
                WheelchairContent::Inform(Fact::AtPose { agent, pose }) => {
                    assert_eq!(agent.name, "chair1");
                    poses.push(pose);
                }
                WheelchairContent::Inform(Fact::Reading {
                    reading: SensorReading::Sonar { ranges_m },
                    ..
                }) => {
                    sonar_seen = true;
                    assert_eq!(ranges_m[0], 1.2);
                }
                other => panic!("unexpected {other:?}"),
            }
        }
        assert!(sonar_seen);
        poses
    };
    assert!(poses.len() >= 15, "{} poses", poses.len());
    let (first, last) = (poses.first().unwrap(), poses.last().unwrap());
    assert!(
        last.x_m > first.x_m + 0.1,
        "drives forward: {} -> {}",
        first.x_m,
        last.x_m
    );
    assert!((last.y_m - 2.0).abs() < 1e-9, "straight along x");
    assert!(
        last.covariance[(0, 0)] > first.covariance[(0, 0)],
        "uncertainty grows without a camera"
    );
    probe.send(
        AclMessage::new(Performative::Cancel)
            .with_receiver(AgentId::new("perception"))
            .with_conversation_id("s1"),
    );
    run(100);
    probe.take_received();
    run(1000);
    assert_eq!(probe.take_received().len(), 0, "no informs after cancel");
}

/// A `width_m` by `depth_m` room with a corner at the origin.
fn room(width_m: f64, depth_m: f64) -> Arc<LocalizationMap> {
    let corners = [
        (0.0, 0.0),
        (width_m, 0.0),
        (width_m, depth_m),
        (0.0, depth_m),
    ]
    .map(|(x, y)| nalgebra::Point2::new(x, y));
    let walls = (0..4).map(|i| (corners[i], corners[(i + 1) % 4])).collect();
    Arc::new(LocalizationMap::new(walls, Vec::new(), 2.0).unwrap())
}

/// `agent` as `perception` on a mock clock, with a probe beside it.
fn beside_a_probe(agent: PerceptionAgent) -> (AgentHost, MockController, GatewayHandle) {
    let (mut host, controller) = AgentHost::on_a_mock_clock(Time::from_ns(1_000_000_000));
    host.add(AgentId::new("perception"), Box::new(agent))
        .unwrap();
    let (agent, probe) = gateway(Duration::from_millis(1));
    host.add(AgentId::new("probe"), Box::new(agent)).unwrap();
    (host, controller, probe)
}

/// Standing still in a room, the sonars echo at 1.2 m, except reads 21..=60 where every
/// sonar reads 65.533 m (the world's `sensor-failure` of the sonars: past any range).
struct GarbledSonars {
    reads: u64,
}

impl Body for GarbledSonars {
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        self.reads += 1;
        let mut frame = SensorFrame::empty(self.reads * 50_000_000);
        let range = if (21..=60).contains(&self.reads) {
            65.533
        } else {
            1.2
        };
        frame.sonar_m = [Some(range); iw_body::SONAR_COUNT];
        Ok(frame)
    }
    fn command(&mut self, _: WheelSpeeds) -> Result<(), BodyError> {
        Ok(())
    }
}

#[test]
fn garbled_sonars_are_reported_dropped_to_every_subscriber_and_back_in_use() {
    let start = Pose2::new(2.0, 2.0, 0.0);
    let config = PerceptionConfig::prototype(AgentId::new("chair1"), start);
    let sonar = SonarGeometry {
        t_base_sonar: Footprint::PROTOTYPE
            .sonar_mounts()
            .iter()
            .map(|m| Pose2::new(m.translation.x, m.translation.y, m.rotation.angle()))
            .collect(),
        max_range_m: 3.0,
        sigma_m: 0.15,
    };
    let localizer = Localizer::new(
        room(4.0, 4.0),
        LocalizerConfig::new(None, Some(sonar), config.drive.alpha),
        Some((start, nalgebra::Matrix3::identity() * 1e-4)),
    );
    let agent = PerceptionAgent::new(config, Box::new(GarbledSonars { reads: 0 }), None)
        .unwrap()
        .with_localizer(localizer);
    let (mut host, controller, probe) = beside_a_probe(agent);
    let subscribe = |conversation: &str| {
        AclMessage::new(Performative::Subscribe)
            .with_receiver(AgentId::new("perception"))
            .with_protocol("fipa-subscribe")
            .with_conversation_id(conversation)
            .with_content("((at-pose ?agent ?pose))")
    };
    let mut run = |ms: u64| {
        for _ in 0..ms / 10 {
            host.step(controller.now());
            controller.advance(Duration::from_millis(10));
        }
    };
    // (conversation, sensor, use, reason) of every sensor-health notification
    let health = |inbox: Vec<AclMessage>| -> Vec<(String, String, SensorUse, String)> {
        inbox
            .iter()
            .filter_map(|m| match WheelchairContent::from_message(m) {
                Ok(WheelchairContent::Inform(Fact::Sensor { agent, state })) => {
                    assert_eq!(agent.name, "chair1");
                    Some((
                        m.conversation_id.clone().unwrap_or_default(),
                        state.sensor,
                        state.usage,
                        state.reason,
                    ))
                }
                _ => None,
            })
            .collect()
    };
    probe.send(subscribe("s1"));
    // well into the garbage: dropped after ten garbled reads in a row
    run(2500);
    let told = health(probe.take_received());
    assert_eq!(told.len(), 1, "{told:?}");
    let (conversation, sensor, usage, reason) = &told[0];
    assert_eq!((conversation.as_str(), sensor.as_str()), ("s1", "sonars"));
    assert_eq!(*usage, SensorUse::Dropped);
    assert!(reason.starts_with("garbage"), "{reason}");
    // a subscriber that comes while the sonars are dropped is told at once
    probe.send(subscribe("s2"));
    run(100);
    let told = health(probe.take_received());
    assert!(
        told.iter()
            .any(|(c, s, u, _)| c == "s2" && s == "sonars" && *u == SensorUse::Dropped),
        "{told:?}"
    );
    // good readings again: both subscribers are told the ring is back, once
    run(2500);
    let told = health(probe.take_received());
    assert_eq!(told.len(), 2, "{told:?}");
    for (conversation, sensor, usage, reason) in &told {
        assert!(conversation == "s1" || conversation == "s2");
        assert_eq!((sensor.as_str(), *usage), ("sonars", SensorUse::InUse));
        assert!(reason.is_empty());
    }
    assert!(probe.take_send_errors().is_empty());
}

/// A chair driving straight at 0.5 m/s for 10 s in a world process whose steps come 40 and 60
/// ms apart (its timer's pattern for a 50 ms period, measured across processes), read every 50
/// ms: each read returns the latest step's ticks and that step's time on the world's clock, so
/// some reads repeat a step and some skip one.
struct UnevenWorldSteps {
    reads: u64,
    m_per_tick: f64,
}

impl UnevenWorldSteps {
    const SPEED_MPS: f64 = 0.5;
    const DRIVE_NS: u64 = 10_000_000_000;

    /// The last world step at or before `t_ns`.
    fn step_at(t_ns: u64) -> u64 {
        // steps at 0, 40, 100, 140, 200, ... ms
        let pair = t_ns / 100_000_000 * 100_000_000;
        if t_ns - pair >= 40_000_000 {
            pair + 40_000_000
        } else {
            pair
        }
    }

    /// Where the world has the chair at `t_ns`, m along x from its start.
    fn travel_m(t_ns: u64) -> f64 {
        Self::SPEED_MPS * t_ns.min(Self::DRIVE_NS) as f64 * 1e-9
    }
}

impl Body for UnevenWorldSteps {
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        self.reads += 1;
        let now_ns = self.reads * 50_000_000;
        let step_ns = Self::step_at(now_ns);
        let ticks = (Self::travel_m(step_ns) / self.m_per_tick).round() as i64;
        Ok(SensorFrame {
            left_ticks: ticks,
            right_ticks: ticks,
            ticks_time_ns: step_ns,
            ..SensorFrame::empty(now_ns)
        })
    }
    fn command(&mut self, _: WheelSpeeds) -> Result<(), BodyError> {
        Ok(())
    }
}

/// The slip model takes each step's speeds from the time its ticks took on the body's clock:
/// dead-reckoning on a world process's uneven steps at a constant speed, the chair is where the
/// world has it (the start from rest costs 5 mm). Taken one control period each, the steps'
/// travel changed by half from read to read and the slip model's one-sided loss shortened the
/// drive: across processes a chair fell 11 cm behind in 10 s of dead reckoning, and the scans,
/// when they came back, were gated out until it was taken for lost.
#[test]
fn a_chair_dead_reckoning_on_uneven_world_steps_keeps_up_with_the_world() {
    let start = Pose2::new(1.0, 2.0, 0.0);
    let config = PerceptionConfig::prototype(AgentId::new("chair1"), start);
    let m_per_tick = config.drive.geometry().m_per_tick();
    // a long room with no range sensor: the localizer dead-reckons
    let localizer = Localizer::new(
        room(20.0, 4.0),
        LocalizerConfig {
            acceleration_slip: Some(AccelerationSlip {
                per_mps2: 0.02,
                period_s: 0.05,
                track_m: config.drive.track_m,
            }),
            ..LocalizerConfig::new(None, None, config.drive.alpha)
        },
        Some((start, nalgebra::Matrix3::identity() * 1e-6)),
    );
    let body = UnevenWorldSteps {
        reads: 0,
        m_per_tick,
    };
    let agent = PerceptionAgent::new(config, Box::new(body), None)
        .unwrap()
        .with_localizer(localizer);
    let (mut host, controller, probe) = beside_a_probe(agent);
    probe.send(
        AclMessage::new(Performative::Subscribe)
            .with_receiver(AgentId::new("perception"))
            .with_protocol("fipa-subscribe")
            .with_conversation_id("s1")
            .with_content("((at-pose ?agent ?pose))"),
    );
    // the drive and two seconds standing
    for _ in 0..1200 {
        host.step(controller.now());
        controller.advance(Duration::from_millis(10));
    }
    let last = probe
        .take_received()
        .iter()
        .rev()
        .find_map(|m| match WheelchairContent::from_message(m) {
            Ok(WheelchairContent::Inform(Fact::AtPose { pose, .. })) => Some(pose),
            _ => None,
        })
        .expect("poses published");
    // the odometry starts at the first read's ticks, the first step's 20 mm already driven
    let driven = UnevenWorldSteps::travel_m(UnevenWorldSteps::DRIVE_NS)
        - UnevenWorldSteps::travel_m(UnevenWorldSteps::step_at(50_000_000));
    let behind = start.x + driven - last.x_m;
    eprintln!("dead-reckoned {driven} m: {behind} m behind the world");
    assert!(
        (0.0..0.01).contains(&behind),
        "{behind} m behind the world after {driven} m"
    );
}
