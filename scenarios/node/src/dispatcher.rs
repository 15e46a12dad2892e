//! The service container's dispatcher agent: it subscribes to the pose of every chair that joins,
//! and gives each chair its configured goal as an A*-planned action sequence from where the chair
//! reports it is (the staff's role of the fleet's operator, across processes).

use std::collections::{BTreeMap, BTreeSet};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, Context};
use iw_bus::Time;
use iw_cognitive::OccupancyGrid;
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{Fact, WheelchairAction, WheelchairContent};
use nalgebra::Point2;

use crate::event::Event;

/// The agents of other containers currently present, kept by the runtime from the GAL.
pub type Roster = Arc<Mutex<BTreeSet<String>>>;

/// Spacing of the waypoints sent to a chair, m.
const WAYPOINT_SPACING_M: f64 = 1.0;

/// The points of an A* path the control agent drives to one after the other: a point every
/// `spacing_m` along the path, and its end.
fn waypoints(path: &[Point2<f64>], spacing_m: f64) -> Vec<Point2<f64>> {
    let mut kept: Vec<Point2<f64>> = Vec::new();
    let mut last = path.first().copied();
    for (i, here) in path.iter().enumerate().skip(1) {
        if i + 1 == path.len() || last.is_some_and(|l| (here - l).norm() >= spacing_m) {
            kept.push(*here);
            last = Some(*here);
        }
    }
    kept
}

/// Why a chair refused or failed a goal: the text of an `((error-message "..."))` content as
/// the chair's agents send it, else the content as received; `None` for other answers.
fn answer_reason(message: &AclMessage) -> Option<String> {
    if !matches!(
        message.performative,
        Performative::Failure | Performative::Refuse | Performative::NotUnderstood
    ) {
        return None;
    }
    let text = message.content_text().unwrap_or_default().trim();
    let said = iw_sl::parse(text, iw_sl::Level::Full)
        .ok()
        .and_then(|content| match content.expressions.as_slice() {
            [iw_sl::ContentExpression::Formula(iw_sl::Formula::Atomic { predicate, args })]
                if predicate == "error-message" =>
            {
                match args.as_slice() {
                    [
                        iw_sl::Term::Constant {
                            value: iw_sl::Constant::String(why),
                        },
                    ] => Some(why.clone()),
                    _ => None,
                }
            }
            _ => None,
        });
    Some(said.unwrap_or_else(|| {
        if text.is_empty() {
            "(no reason given)".to_string()
        } else {
            text.to_string()
        }
    }))
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum GoalState {
    /// Waiting for the chair's first pose.
    Waiting,
    /// Requested; the conversation number.
    Sent(u64),
}

struct Goal {
    chair: String,
    place: String,
    target: Point2<f64>,
    state: GoalState,
}

/// See the module docs.
pub struct Dispatcher {
    grid: OccupancyGrid,
    goals: Vec<Goal>,
    roster: Roster,
    subscribed: BTreeSet<String>,
    last_report: BTreeMap<String, Time>,
    report_every: Duration,
    conversations: u64,
    events: Sender<Event>,
}

impl Dispatcher {
    /// A dispatcher planning on `grid`, with `goals` (chair, place name, place) to give, reporting
    /// poses at most every `report_every`.
    pub fn new(
        grid: OccupancyGrid,
        goals: Vec<(String, String, Point2<f64>)>,
        roster: Roster,
        report_every: Duration,
        events: Sender<Event>,
    ) -> Self {
        let goals = goals
            .into_iter()
            .map(|(chair, place, target)| Goal {
                chair,
                place,
                target,
                state: GoalState::Waiting,
            })
            .collect();
        Dispatcher {
            grid,
            goals,
            roster,
            subscribed: BTreeSet::new(),
            last_report: BTreeMap::new(),
            report_every,
            conversations: 0,
            events,
        }
    }

    fn emit(&self, event: Event) {
        // the receiver lives as long as the runtime that steps this agent
        let _ = self.events.send(event);
    }

    fn on_pose(
        &mut self,
        ctx: &mut Context<'_>,
        chair: &str,
        position: Point2<f64>,
        theta_rad: f64,
    ) {
        let due = self
            .last_report
            .get(chair)
            .is_none_or(|last| ctx.now() >= last.plus(self.report_every));
        if due {
            self.last_report.insert(chair.to_string(), ctx.now());
            self.emit(Event::Pose {
                chair: chair.into(),
                x_m: position.x,
                y_m: position.y,
                theta_rad,
            });
        }
        let Some(i) = self
            .goals
            .iter()
            .position(|g| g.chair == chair && g.state == GoalState::Waiting)
        else {
            return;
        };
        self.conversations += 1;
        let number = self.conversations;
        self.goals[i].state = GoalState::Sent(number);
        let goal = &self.goals[i];
        let conversation = format!("goal-{chair}-{number}");
        let failed = |reason: String| Event::Goal {
            chair: chair.into(),
            place: goal.place.clone(),
            conversation: conversation.clone(),
            performative: Performative::Failure.to_string(),
            reason: Some(reason),
        };
        let path = match self.grid.astar(position, goal.target) {
            Ok(path) => path,
            Err(e) => return self.emit(failed(format!("no path to `{}`: {e}", goal.place))),
        };
        let steps = waypoints(&path.waypoints, WAYPOINT_SPACING_M)
            .into_iter()
            .map(|p| WheelchairAction::GotoXy { x_m: p.x, y_m: p.y })
            .collect();
        let actor = AgentId::new(format!("control@{chair}"));
        let request = WheelchairContent::Request {
            actor: actor.clone(),
            action: WheelchairAction::Sequence { steps },
        }
        .fill(
            AclMessage::new(Performative::Request)
                .with_receiver(actor)
                .with_protocol("fipa-request")
                .with_conversation_id(conversation.clone()),
        );
        if let Err(e) = ctx.send(request) {
            self.emit(failed(e.to_string()));
        }
    }

    fn on_answer(&self, message: &AclMessage) {
        let Some(conversation) = message.conversation_id.as_deref() else {
            return;
        };
        let goal = self.goals.iter().find(|g| matches!(g.state, GoalState::Sent(n) if conversation == format!("goal-{}-{n}", g.chair)));
        if let Some(goal) = goal {
            self.emit(Event::Goal {
                chair: goal.chair.clone(),
                place: goal.place.clone(),
                conversation: conversation.into(),
                performative: message.performative.to_string(),
                reason: answer_reason(message),
            });
        }
    }
}

impl Agent for Dispatcher {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        if message.performative == Performative::Inform
            && let Ok(WheelchairContent::Inform(Fact::AtPose { agent, pose })) =
                WheelchairContent::from_message(&message)
        {
            let position = Point2::new(pose.x_m, pose.y_m);
            return self.on_pose(ctx, &agent.name, position, pose.theta_rad);
        }
        if message
            .conversation_id
            .as_deref()
            .is_some_and(|c| c.starts_with("goal-"))
        {
            self.on_answer(&message);
        }
    }

    fn tick(&mut self, ctx: &mut Context<'_>) {
        let present: BTreeSet<String> = self
            .roster
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone();
        // A chair that left loses its subscription and gets its goal again when it is back.
        let gone: Vec<String> = self
            .subscribed
            .iter()
            .filter(|c| !present.contains(&format!("perception@{c}")))
            .cloned()
            .collect();
        for chair in gone {
            self.subscribed.remove(&chair);
            for goal in self.goals.iter_mut().filter(|g| g.chair == chair) {
                goal.state = GoalState::Waiting;
            }
        }
        for agent in &present {
            let Some(chair) = agent.strip_prefix("perception@") else {
                continue;
            };
            if self.subscribed.contains(chair) {
                continue;
            }
            let subscribe = AclMessage::new(Performative::Subscribe)
                .with_receiver(AgentId::new(agent.clone()))
                .with_protocol("fipa-subscribe")
                .with_ontology(iw_ontology::wheelchair::ONTOLOGY)
                .with_language("fipa-sl0")
                .with_conversation_id(format!("pose-{chair}-{}", ctx.name()))
                .with_content("((at-pose ?agent ?pose))");
            if ctx.send(subscribe).is_ok() {
                self.subscribed.insert(chair.to_string());
            }
        }
    }

    fn tick_period(&self) -> Option<Duration> {
        Some(Duration::from_millis(100))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn answer(performative: Performative, content: &str) -> AclMessage {
        AclMessage::new(performative).with_content(content.to_string())
    }

    #[test]
    fn a_chairs_reason_reaches_the_goal_event() {
        let failure = answer(
            Performative::Failure,
            "((error-message \"blocked for 5.0 s at (2.1, 3.0)\"))",
        );
        assert_eq!(
            answer_reason(&failure).as_deref(),
            Some("blocked for 5.0 s at (2.1, 3.0)")
        );
        // A reason in another form is kept as sent, never dropped.
        let refuse = answer(Performative::Refuse, "((unauthorised))");
        assert_eq!(answer_reason(&refuse).as_deref(), Some("((unauthorised))"));
        let bare = answer(Performative::NotUnderstood, "");
        assert_eq!(answer_reason(&bare).as_deref(), Some("(no reason given)"));
        assert_eq!(answer_reason(&answer(Performative::Agree, "((x))")), None);
    }
}
