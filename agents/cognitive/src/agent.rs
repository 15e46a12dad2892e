//! The cognitive agent: takes a global goal, plans intermediate objectives (places and doors)
//! with the PDDL planner, paths with A*, and has the control and door agents carry them out;
//! re-plans when a door is refused or a path is blocked, and detours past a landmark
//! when the pose uncertainty grows past a threshold (thesis 3.8).
//!
//! # Messages
//! All `:ontology IntellWheels-Wheelchair`, `:language fipa-sl0`, `:protocol fipa-request`.
//! - Understood: REQUEST `((action (agent-identifier :name ME) (go-to :place P)))` from the
//!   interface or assistant agent. Answer: AGREE (REFUSE for a place not on the map), then INFORM
//!   `((done (action ME (go-to :place P))))` on arrival or FAILURE `((error-message "..."))` when
//!   no route is left. A newer goal replaces the running one (the old one gets FAILURE).
//! - Understood: QUERY-REF `((current-goal ME ?goal))` (`fipa-query`) from anyone. Answer: INFORM
//!   `((current-goal ME (set (goal :place P :requester R :conversation C))))`, the goal under way
//!   and the conversation it will be answered in, and the last goal that ended with its
//!   `:outcome` (told once to each agent that asks: its answer may have gone to a requester that
//!   is gone, and the services and the assistant may both ask about it); an empty set
//!   when there is neither. A query about another agent is refused. The services ask this when
//!   a chair joins them, so a goal whose requester they no longer know (they restarted) is given
//!   again, failed or reported ended, not lost; the assistant asks it about a goal it forwarded
//!   that went unanswered (`iw_assistant::GOAL_CHECK`), so an answer lost on the way still ends
//!   the goal for staff.
//! - Understood: INFORM `((at-pose agent (pose ...)))` from the perception agent, subscribed at
//!   setup with SUBSCRIBE `((at-pose ?agent ?pose))` (`fipa-subscribe`) when
//!   [`CognitiveConfig::perception`] is set.
//! - Sent to the door agent: REQUEST `((action (agent-identifier :name DOOR) (open-door :door D)))`;
//!   INFORM done = open; REFUSE or FAILURE = the door is treated as locked and the goal re-planned.
//! - Sent to the control agent: REQUEST `((action (agent-identifier :name CONTROL)
//!   (action-sequence :steps (sequence (goto-xy :x :y) ...))))`, one per `move` or `pass-door`
//!   step; INFORM done = next step; FAILURE = that connection is treated as blocked and the goal
//!   re-planned, except FAILURE `((body-fault "..."))`: the chair's body failed (its world link
//!   down, its sensors or board unreadable), which says nothing of the way, so the goal fails at
//!   once with the body's reason (staff see why; a re-plan would only report "no route"). Each step has its own conversation id (`cog-N`); answers to an abandoned step
//!   are ignored. Goals, steps and the pose subscription run on the interaction protocols'
//!   state machines (`iw_agent::conversation`): an answer out of protocol changes nothing.
//! - Sent to the watcher agent, when [`CognitiveConfig::watcher`] is set and a motion crosses one
//!   of the map's narrow passages: the chair first drives to [`crate::passage::WAIT_BACK_M`]
//!   before the passage and stops, SUBSCRIBEs (`fipa-subscribe`: the grant is a subscription,
//!   see the watcher's crate) to `((action W (pass :passage P :direction D)))`, drives through
//!   on the INFORM done that notifies the grant, and CANCELs that subscription once a pose shows
//!   it clear (it does not stop there). The passage is let go at once; the watcher's
//!   confirmation (INFORM `((done (action W (cancel (action W (pass ...))))))`, FIPA's cancel
//!   meta-protocol) is waited for up to [`CANCEL_CONFIRM_TIMEOUT`], and a missing or failed one
//!   is logged. A FAILURE in a held subscription (its lease ran out)
//!   ends the grant. REFUSE or NOT-UNDERSTOOD (the passage is not watched), or no AGREE within
//!   [`PASS_ANSWER_TIMEOUT`] (the watcher is unreachable), or no grant within
//!   [`CognitiveConfig::pass_wait`]: the chair leaves the queue (CANCEL) and goes on, its own
//!   guard keeping it safe.
//!
//! Landmarks: before a motion step, and whenever a pose arrives during one, if the pose's
//! variance in its worst direction ([`worst_variance_m2`], the larger eigenvalue of the x-y
//! covariance) exceeds [`CognitiveConfig::uncertainty_m2`] above its lowest since the last
//! landmark visit, the step is re-issued via the landmark on the way (the shortest detour to the
//! step's place; [`LandmarkStop`]: on the marker's axis, so the camera faces it on the way in).
//! The worst direction, not the trace: a door is missed by the error across it, and a trace can
//! hide all of its variance in one direction (twice the standard deviation there). The same
//! happens once when the perception agent says it dropped the laser (INFORM
//! `((sensor-health agent (sensor-state :sensor laser :use dropped ...)))` in the pose
//! subscription): the chair dead-reckons from then on, and a landmark is what can still reset
//! its error.
//!
//! A detour never goes back to the landmark visited last: a chair whose error grows fast (a
//! dropped laser) passes the threshold again a few metres past a landmark, and the landmark
//! behind it can still be the shortest detour, so it would shuttle between two points and never
//! get on. With no other landmark on the map there is no detour; the chair goes on.
//!
//! Measured at the default threshold ([`LANDMARK_UNCERTAINTY_M2`]; the commands and figures are
//! on the localization results page, "The landmark detour on the worst direction"): with the
//! laser in use the worst direction's variance stays under 1e-4 m² (no detour in the demo,
//! `head-on` or the scenario files); blind, a chair passes it about 5 m past a landmark.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::conversation::answers_a_conversation;
use iw_agent::{Agent, Context, EventKind, Initiated, Progress, Protocol, Responder};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{
    Fact, GoalInFlight, Pose, SensorState, SensorUse, Subscription, Topic, WheelchairAction,
    WheelchairContent,
};
use nalgebra::Point2;

use crate::passage::{Leg, NarrowPassage, legs, touched};
use crate::pddl::{Atom, Domain, Literal, Problem, Term};
use crate::planner::{Step, plan};
use crate::{GridError, OccupancyGrid};

/// A goal that ended and the agents told it so far (at most [`ENDED_TOLD_MAX`]; past that a
/// querier may be told it again, a repeated answer rather than a lost one).
#[derive(Debug)]
struct EndedGoal {
    goal: GoalInFlight,
    told: BTreeSet<String>,
}

/// Agents remembered as told an ended goal: the services and an assistant or two in practice.
const ENDED_TOLD_MAX: usize = 32;

/// Why the cognitive agent cannot be built.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CognitiveError {
    /// A connection or door names a place that is not on the map.
    #[error("the map's {what} names place `{place}`, which is not among its places")]
    UnknownPlace {
        /// `connection`, `door`, or `start`.
        what: &'static str,
        /// The place.
        place: String,
    },
    /// A place or landmark lies in an obstacle or off the grid.
    #[error("map point `{name}`: {source}")]
    BadPoint {
        /// The place or landmark.
        name: String,
        /// Why A* would refuse it.
        source: GridError,
    },
}

/// A door between two places: where the chair crosses it.
#[derive(Debug, Clone, PartialEq)]
pub struct DoorPassage {
    /// The door's name (as the door agent knows it).
    pub name: String,
    /// One side.
    pub a: String,
    /// The other side.
    pub b: String,
    /// The middle of the doorway, map frame, m.
    pub at: Point2<f64>,
}

/// Where the chair relocalises: the point it stops at, and the point it comes from so that its
/// camera faces the marker on the way in (a chair arriving along its path sees the marker only
/// when the path happens to come from the marker's side).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LandmarkStop {
    /// Where the chair stops, map frame, m.
    pub at: Point2<f64>,
    /// Where it drives to first, on the marker's axis behind `at`; `None` for a landmark place
    /// with no marker to face.
    pub from: Option<Point2<f64>>,
}

/// The building as the strategic layer sees it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BuildingMap {
    /// Named places and the point the chair drives to in each, map frame, m.
    pub places: BTreeMap<String, Point2<f64>>,
    /// Places joined without a door (both directions).
    pub connections: Vec<(String, String)>,
    /// Doors between places.
    pub doors: Vec<DoorPassage>,
    /// Landmarks the chair can relocalise at.
    pub landmarks: Vec<LandmarkStop>,
    /// Narrow passages the watcher lets chairs through one direction at a time.
    pub passages: Vec<NarrowPassage>,
}

/// Who the cognitive agent talks to and what it knows.
#[derive(Debug, Clone)]
pub struct CognitiveConfig {
    /// The chair's object name in the planning problem, e.g. `chair1`.
    pub chair: String,
    /// The chair's control agent.
    pub control: AgentId,
    /// The door agent.
    pub door: AgentId,
    /// The perception agent to subscribe to for poses.
    pub perception: Option<AgentId>,
    /// The watcher agent to ask for narrow passages; `None` drives straight through them.
    pub watcher: Option<AgentId>,
    /// Longest wait for the watcher's grant before the chair goes on regardless.
    pub pass_wait: Duration,
    /// The planning domain (`domains/building.pddl`).
    pub domain: Domain,
    /// Places, connections, doors, landmarks.
    pub map: BuildingMap,
    /// The occupancy grid of the map (not inflated).
    pub grid: OccupancyGrid,
    /// Obstacles are inflated by this for path planning, m.
    pub chair_radius_m: f64,
    /// Where the chair starts (a place of the map).
    pub start_place: String,
    /// Growth of the pose's variance in its worst direction ([`worst_variance_m2`]) since the
    /// last landmark above which the chair detours via a landmark, m².
    pub uncertainty_m2: f64,
    /// Planner state budget.
    pub max_states: usize,
}

/// The default of [`CognitiveConfig::uncertainty_m2`], m²: 10 cm standard deviation in the
/// worst direction, 2 sigma 20 cm. A 1.5 m opening leaves a 0.6 m chair 45 cm each side, and
/// 20 cm of error leaves 25 cm of that for the guard. The trace's old 0.04 m² could mean 40 cm
/// (2 sigma) in one direction, as along a blank corridor.
pub const LANDMARK_UNCERTAINTY_M2: f64 = 0.01;

/// A passage is let go when a pose is this close to its release point, m (poses come at a few
/// hertz, the chair drives at about half a metre a second).
pub const RELEASE_RADIUS_M: f64 = 0.6;

/// How long the watcher has to agree to a pass request before it is taken for unreachable.
pub const PASS_ANSWER_TIMEOUT: Duration = Duration::from_secs(2);

/// How long the watcher's confirmation of a CANCEL is waited for before the conversation is
/// forgotten with a warning (the chair has let the passage go already).
pub const CANCEL_CONFIRM_TIMEOUT: Duration = Duration::from_secs(5);

/// The building domain shipped with the crate.
pub const BUILDING_DOMAIN: &str = include_str!("../domains/building.pddl");

struct Goal {
    /// The goal's conversation with whoever gave it.
    responder: Responder,
    actor: AgentId,
    place: String,
    plan: Vec<Step>,
    next: usize,
}

/// A motion step of the plan: to place `to` from `from` (through `door`).
#[derive(Debug, Clone, PartialEq)]
struct Motion {
    from: String,
    to: String,
    door: Option<String>,
    /// The landmark stop it goes past first, until the chair has been there.
    landmark: Option<Point2<f64>>,
}

/// The plan step that waits for another agent's answer (one at a time).
#[derive(Debug, Clone, PartialEq)]
enum Waiting {
    /// A door to open.
    Door { door: String },
    /// The control agent driving a leg of `motion`.
    Drive { motion: Motion },
    /// The watcher's grant of `passage` for `motion`, subscribed to at `asked_ns` (bus time).
    Pass {
        motion: Motion,
        passage: String,
        asked_ns: u64,
        agreed: bool,
    },
}

/// A passage subscription cancelled (let go, or left while queued), until the watcher confirms.
#[derive(Debug)]
struct Releasing {
    passage: String,
    /// When the CANCEL went, bus time (ns).
    since_ns: u64,
}

/// The cognitive agent of one wheelchair.
pub struct CognitiveAgent {
    config: CognitiveConfig,
    grid: OccupancyGrid,
    place: String,
    t_map_base: Option<Point2<f64>>,
    /// The last pose's variance in its worst direction, m².
    uncertainty_m2: f64,
    /// Its lowest since the last landmark visit, m².
    uncertainty_at_landmark_m2: f64,
    /// The stop of the landmark visited last, which the next detour does not go back to.
    last_landmark: Option<Point2<f64>>,
    /// Whether the last pose said the chair knows where it is (true until a pose says not).
    localized: bool,
    /// The laser was dropped and no landmark has been visited since: the next motion (or the
    /// one under way) goes past a landmark.
    landmark_owed: bool,
    open_doors: BTreeSet<String>,
    locked_doors: BTreeSet<String>,
    blocked: BTreeSet<(String, String)>,
    goal: Option<Goal>,
    /// The last goal that ended (not replaced), and who has been told it.
    ended: Option<EndedGoal>,
    /// The request of the step under way (at most one; a new step abandons the last).
    pending: Initiated<Waiting>,
    /// The pose subscription to the perception agent.
    poses: Initiated<()>,
    /// What is left of the motion step under way.
    legs: VecDeque<Leg>,
    /// Passages granted to this chair (by name), each a live subscription with the watcher.
    held: Initiated<String>,
    /// Passages to let go when the chair gets to a point of the drive under way.
    releases: Vec<(String, Point2<f64>)>,
    /// Passage subscriptions cancelled, waiting for the watcher's confirmation.
    releasing: Initiated<Releasing>,
    conversations: u64,
}

impl CognitiveAgent {
    /// A cognitive agent; checks the map against the grid.
    pub fn new(config: CognitiveConfig) -> Result<Self, CognitiveError> {
        let grid = config.grid.inflated(config.chair_radius_m);
        let known = |what, place: &String| {
            if config.map.places.contains_key(place) {
                Ok(())
            } else {
                Err(CognitiveError::UnknownPlace {
                    what,
                    place: place.clone(),
                })
            }
        };
        known("start", &config.start_place)?;
        for (a, b) in &config.map.connections {
            known("connection", a)?;
            known("connection", b)?;
        }
        for door in &config.map.doors {
            known("door", &door.a)?;
            known("door", &door.b)?;
        }
        let points = config.map.places.iter().map(|(n, p)| (n.clone(), *p));
        let landmarks = config.map.landmarks.iter().enumerate().flat_map(|(i, l)| {
            std::iter::once(l.at)
                .chain(l.from)
                .map(move |p| (format!("landmark {i}"), p))
        });
        for (name, p) in points.chain(landmarks) {
            grid.astar(p, p)
                .map_err(|source| CognitiveError::BadPoint { name, source })?;
        }
        Ok(CognitiveAgent {
            place: config.start_place.clone(),
            grid,
            config,
            t_map_base: None,
            uncertainty_m2: 0.0,
            localized: true,
            landmark_owed: false,
            uncertainty_at_landmark_m2: 0.0,
            last_landmark: None,
            open_doors: BTreeSet::new(),
            locked_doors: BTreeSet::new(),
            blocked: BTreeSet::new(),
            goal: None,
            ended: None,
            pending: Initiated::new(),
            poses: Initiated::new(),
            legs: VecDeque::new(),
            held: Initiated::new(),
            releases: Vec::new(),
            releasing: Initiated::new(),
            conversations: 0,
        })
    }

    /// The planning problem from the current place to `place` with what is known of doors and
    /// blocked connections.
    fn problem(&self, place: &str) -> Problem {
        let c = |s: &str| Term::Const(s.to_string());
        let atom = |predicate: &str, args: Vec<Term>| Atom {
            predicate: predicate.to_string(),
            args,
        };
        let map = &self.config.map;
        let mut objects = vec![(self.config.chair.clone(), "chair".to_string())];
        objects.extend(map.places.keys().map(|p| (p.clone(), "place".to_string())));
        objects.extend(
            map.doors
                .iter()
                .map(|d| (d.name.clone(), "door".to_string())),
        );
        let mut init = vec![atom("at", vec![c(&self.config.chair), c(&self.place)])];
        let free = |a: &String, b: &String| !self.blocked.contains(&(a.clone(), b.clone()));
        for (a, b) in &map.connections {
            for (x, y) in [(a, b), (b, a)] {
                if free(x, y) {
                    init.push(atom("connected", vec![c(x), c(y)]));
                }
            }
        }
        for d in &map.doors {
            for (x, y) in [(&d.a, &d.b), (&d.b, &d.a)] {
                if free(x, y) {
                    init.push(atom("through", vec![c(x), c(y), c(&d.name)]));
                }
            }
            if self.open_doors.contains(&d.name) {
                init.push(atom("open", vec![c(&d.name)]));
            }
            if self.locked_doors.contains(&d.name) {
                init.push(atom("locked", vec![c(&d.name)]));
            }
        }
        let goal = vec![Literal {
            positive: true,
            atom: atom("at", vec![c(&self.config.chair), c(place)]),
        }];
        Problem {
            name: "route".into(),
            domain: self.config.domain.name.clone(),
            objects,
            init,
            goal,
        }
    }

    fn conversation(&mut self) -> String {
        self.conversations += 1;
        format!("cog-{}", self.conversations)
    }

    /// Plans from the current place and starts the first step; ends the goal when done or stuck.
    fn replan(&mut self, ctx: &mut Context<'_>) {
        let Some(place) = self.goal.as_ref().map(|g| g.place.clone()) else {
            return;
        };
        match plan(
            &self.config.domain,
            &self.problem(&place),
            self.config.max_states,
        ) {
            Ok(steps) => {
                tracing::info!(chair = %self.config.chair, plan = ?steps.iter().map(ToString::to_string).collect::<Vec<_>>(), "planned");
                if let Some(goal) = self.goal.as_mut() {
                    goal.plan = steps;
                    goal.next = 0;
                }
                self.advance(ctx);
            }
            Err(err) => self.finish(ctx, Err(format!("no route to {place}: {err}"))),
        }
    }

    /// Starts the next plan step, or reports the goal reached.
    fn advance(&mut self, ctx: &mut Context<'_>) {
        let Some(goal) = self.goal.as_mut() else {
            return;
        };
        let Some(step) = goal.plan.get(goal.next).cloned() else {
            self.finish(ctx, Ok(()));
            return;
        };
        goal.next += 1;
        match (step.action.as_str(), step.args.as_slice()) {
            ("open-door", [_, _, _, door]) => {
                let action = WheelchairAction::OpenDoor { door: door.clone() };
                let waiting = Waiting::Door { door: door.clone() };
                self.ask(ctx, self.config.door.clone(), action, waiting);
            }
            ("move", [_, from, to]) => self.motion(ctx, from.clone(), to.clone(), None),
            ("pass-door", [_, from, to, door]) => {
                self.motion(ctx, from.clone(), to.clone(), Some(door.clone()))
            }
            _ => self.finish(
                ctx,
                Err(format!(
                    "the domain's action {step} is not one this agent executes"
                )),
            ),
        }
    }

    /// Sends the control agent the waypoints from here to place `to` (through the door, past a
    /// landmark when the pose is too uncertain).
    fn motion(&mut self, ctx: &mut Context<'_>, from: String, to: String, door: Option<String>) {
        let map = &self.config.map;
        let here = self
            .t_map_base
            .or_else(|| map.places.get(&self.place).copied());
        let (Some(here), Some(target)) = (here, map.places.get(&to).copied()) else {
            self.finish(ctx, Err(format!("place `{to}` has no position")));
            return;
        };
        let doorway = door
            .as_ref()
            .and_then(|d| map.doors.iter().find(|p| &p.name == d))
            .map(|d| d.at);
        let via_landmark = self.landmark_owed || self.too_uncertain();
        let landmark = via_landmark
            .then(|| self.landmark_on_the_way(here, doorway.unwrap_or(target)))
            .flatten();
        let mut stops = Vec::new();
        if let Some(landmark) = landmark {
            stops.extend(landmark.from);
            stops.push(landmark.at);
        }
        stops.extend(doorway);
        stops.push(target);
        let mut waypoints = Vec::new();
        let mut start = here;
        for stop in stops {
            let leg = self.grid.astar(start, stop).or_else(|_| {
                self.grid
                    .astar(map.places.get(&from).copied().unwrap_or(start), stop)
            });
            match leg {
                Ok(path) => waypoints.extend(path.waypoints.into_iter().skip(1)),
                Err(err) => {
                    tracing::warn!(from = %from, to = %to, error = %err, "no path on the grid; connection treated as blocked");
                    self.blocked.insert((from.clone(), to.clone()));
                    self.replan(ctx);
                    return;
                }
            }
            start = stop;
        }
        let motion = Motion {
            from,
            to,
            door,
            landmark: landmark.map(|l| l.at),
        };
        if self.config.watcher.is_none() {
            self.legs = VecDeque::from([Leg::Drive(waypoints)]);
            self.next_leg(ctx, motion);
            return;
        }
        let path: Vec<Point2<f64>> = std::iter::once(here).chain(waypoints).collect();
        // A passage held from before that this path does not enter is let go now.
        let touched = touched(&path, &self.config.map.passages);
        let stale: Vec<String> = self
            .held
            .iter()
            .filter(|(_, held)| !touched.contains(held.as_str()))
            .map(|(_, held)| held.clone())
            .collect();
        for passage in stale {
            self.release(ctx, &passage);
        }
        let held = self.held.iter().map(|(_, held)| held.clone()).collect();
        self.releases.clear();
        self.legs = legs(&path, &self.config.map.passages, &held).into();
        tracing::debug!(chair = %self.config.chair, legs = ?self.legs, "motion legs");
        self.next_leg(ctx, motion);
    }

    /// The landmark whose detour from `here` to `next` (the doorway or the place the chair drives
    /// to) is shortest on the grid (coming in on
    /// its marker's axis): the one on the way, not merely the nearest, which may lie behind the
    /// chair, so that the next detour would send it back there again and again. Never the one
    /// visited last.
    fn landmark_on_the_way(&self, here: Point2<f64>, next: Point2<f64>) -> Option<LandmarkStop> {
        let length = |from: Point2<f64>, to: Point2<f64>| {
            self.grid.astar(from, to).ok().map(|path| path.length_m)
        };
        self.detour_landmarks()
            .filter_map(|l| {
                let approach = l.from.unwrap_or(l.at);
                let detour =
                    length(here, approach)? + (l.at - approach).norm() + length(l.at, next)?;
                Some((detour, *l))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, l)| l)
    }

    /// Starts the next leg of `motion`, or completes the motion step when none is left.
    fn next_leg(&mut self, ctx: &mut Context<'_>, motion: Motion) {
        loop {
            match self.legs.pop_front() {
                None => {
                    self.place = motion.to;
                    if let Some(at) = motion.landmark {
                        // driven past it without a pose there: what it did is what it did
                        self.landmark_visited(at);
                    }
                    if let Some(door) = motion.door {
                        // The door closes behind the chair.
                        self.open_doors.remove(&door);
                    }
                    self.abandon(ctx);
                    self.advance(ctx);
                    return;
                }
                Some(leg @ (Leg::Drive(_) | Leg::Release { .. })) => {
                    // Drives up to the next passage to ask for, in one go: the chair drives on
                    // past release points, and a passage is let go when a pose shows the chair
                    // there (or when the drive ends).
                    self.legs.push_front(leg);
                    let mut points = Vec::new();
                    while let Some(Leg::Drive(_) | Leg::Release { .. }) = self.legs.front() {
                        match self.legs.pop_front() {
                            Some(Leg::Drive(more)) => points.extend(more),
                            Some(Leg::Release { passage, at }) => self.releases.push((passage, at)),
                            _ => {}
                        }
                    }
                    if points.is_empty() {
                        self.release_reached(ctx, |_| true);
                        continue;
                    }
                    let steps = points
                        .into_iter()
                        .map(|p| WheelchairAction::GotoXy { x_m: p.x, y_m: p.y })
                        .collect();
                    let action = WheelchairAction::Sequence { steps };
                    self.ask(
                        ctx,
                        self.config.control.clone(),
                        action,
                        Waiting::Drive { motion },
                    );
                    return;
                }
                Some(Leg::Acquire { passage, direction }) => {
                    let Some(watcher) = self.config.watcher.clone() else {
                        continue;
                    };
                    let action = WheelchairAction::Pass {
                        passage: passage.clone(),
                        direction: direction.to_string(),
                    };
                    tracing::info!(chair = %self.config.chair, passage = %passage, direction, "waiting for the passage");
                    let waiting = Waiting::Pass {
                        motion,
                        passage,
                        asked_ns: ctx.now().0,
                        agreed: false,
                    };
                    self.ask(ctx, watcher, action, waiting);
                    return;
                }
            }
        }
    }

    /// Lets go of the passages of the drive under way whose release point `reached` says the
    /// chair is at.
    fn release_reached(&mut self, ctx: &mut Context<'_>, reached: impl Fn(&Point2<f64>) -> bool) {
        let (passed, ahead): (Vec<_>, Vec<_>) = std::mem::take(&mut self.releases)
            .into_iter()
            .partition(|(_, at)| reached(at));
        self.releases = ahead;
        for (passage, _) in passed {
            self.release(ctx, &passage);
        }
    }

    /// Lets the watcher know the chair is out of `passage` (if it holds it): CANCEL of its
    /// subscription, whose confirmation is then awaited in `releasing`.
    fn release(&mut self, ctx: &mut Context<'_>, passage: &str) {
        let Some(id) = self
            .held
            .iter()
            .find(|(_, held)| *held == passage)
            .map(|(id, _)| id.to_string())
        else {
            return;
        };
        cancel(ctx, &mut self.held, &mut self.releasing, &id, passage);
    }

    /// Asks `to` to do `action` as the plan's step under way, in a fresh conversation; the step
    /// before it is abandoned (its late answers are then not ours).
    fn ask(
        &mut self,
        ctx: &mut Context<'_>,
        to: AgentId,
        action: WheelchairAction,
        waiting: Waiting,
    ) {
        self.abandon(ctx);
        let content = WheelchairContent::Request {
            actor: to.clone(),
            action,
        };
        // A grant outlives its answer (held, then released or taken back): a subscription.
        let (act, protocol) = match waiting {
            Waiting::Pass { .. } => (Performative::Subscribe, Protocol::Subscribe),
            _ => (Performative::Request, Protocol::Request),
        };
        let conversation = self.conversation();
        let message = content.fill(
            AclMessage::new(act)
                .with_receiver(to)
                .with_conversation_id(conversation),
        );
        if let Err(err) = self.pending.open(ctx, protocol, message, waiting) {
            self.finish(ctx, Err(format!("could not ask for the next step: {err}")));
        }
    }

    /// Forgets the step under way, if any (its late answers are then not ours); a passage
    /// waited for is cancelled, so the chair leaves the watcher's queue.
    fn abandon(&mut self, ctx: &mut Context<'_>) {
        let Some((id, waiting)) = self.pending.iter().next() else {
            return;
        };
        let id = id.to_string();
        if let Waiting::Pass { passage, .. } = waiting {
            let passage = passage.clone();
            cancel(ctx, &mut self.pending, &mut self.releasing, &id, &passage);
        } else {
            self.pending.forget(&id);
        }
    }

    /// Answers the goal's requester and forgets the goal.
    fn finish(&mut self, ctx: &mut Context<'_>, outcome: Result<(), String>) {
        self.abandon(ctx);
        self.legs.clear();
        self.releases.clear();
        let held: Vec<String> = self.held.iter().map(|(_, held)| held.clone()).collect();
        for passage in held {
            self.release(ctx, &passage);
        }
        let Some(mut goal) = self.goal.take() else {
            return;
        };
        // A replaced goal's story goes on in the newer one; any other end is kept to be told.
        if outcome.as_ref().err().is_none_or(|why| why != REPLACED) {
            self.ended = in_flight(&goal).map(|g| EndedGoal {
                goal: GoalInFlight {
                    outcome: Some(outcome.clone()),
                    ..g
                },
                told: BTreeSet::new(),
            });
        }
        let answered = match outcome {
            Ok(()) => {
                let done = WheelchairContent::Done {
                    actor: goal.actor,
                    action: WheelchairAction::GoTo { place: goal.place },
                };
                ctx.answer(&mut goal.responder, Performative::Inform, &done)
            }
            Err(why) => {
                tracing::warn!(chair = %self.config.chair, reason = %why, "goal failed");
                ctx.answer_error(&mut goal.responder, Performative::Failure, &why)
            }
        };
        if let Err(err) = answered {
            tracing::warn!(chair = %self.config.chair, error = %err, "could not answer the goal");
        }
    }

    fn on_goal(
        &mut self,
        ctx: &mut Context<'_>,
        message: AclMessage,
        actor: AgentId,
        place: String,
    ) {
        let Some(mut responder) = ctx.accept(&message) else {
            return;
        };
        if !self.localized {
            let _ = ctx.answer_error(
                &mut responder,
                Performative::Refuse,
                "not localized: the chair does not know where it is on the map yet; drive it by hand under shared control until it finds itself",
            );
            return;
        }
        if !self.config.map.places.contains_key(&place) {
            let why = format!("unknown place `{place}`");
            let _ = ctx.answer_error(&mut responder, Performative::Refuse, &why);
            return;
        }
        self.finish(ctx, Err(REPLACED.into()));
        let request = WheelchairContent::Request {
            actor: actor.clone(),
            action: WheelchairAction::GoTo {
                place: place.clone(),
            },
        };
        if ctx
            .answer(&mut responder, Performative::Agree, &request)
            .is_err()
        {
            return;
        }
        // A new goal is a fresh chance for doors and passages that failed before.
        self.locked_doors.clear();
        self.blocked.clear();
        self.goal = Some(Goal {
            responder,
            actor,
            place,
            plan: Vec::new(),
            next: 0,
        });
        self.replan(ctx);
    }

    /// Answers a query for the goal under way (its place, requester and conversation).
    fn on_query(&mut self, ctx: &mut Context<'_>, message: &AclMessage) {
        let agent = match WheelchairContent::from_message(message) {
            Ok(WheelchairContent::GoalQuery { agent }) => agent,
            Ok(_) => {
                let _ = ctx.refuse(message, "the cognitive agent answers queries for its goal");
                return;
            }
            Err(err) => {
                let _ = ctx.not_understood(message, &err.to_string());
                return;
            }
        };
        let Some(mut query) = ctx.accept(message) else {
            return;
        };
        if agent.name != ctx.name() {
            let why = format!(
                "{} knows its own goal only, not {}'s",
                ctx.name(),
                agent.name
            );
            let _ = ctx.answer_error(&mut query, Performative::Refuse, &why);
            return;
        }
        let querier = message.sender.as_ref().map(|s| s.name.clone());
        let ended = self
            .ended
            .as_ref()
            .filter(|e| querier.as_ref().is_none_or(|q| !e.told.contains(q)));
        let answer = WheelchairContent::Inform(Fact::CurrentGoal {
            agent: ctx.aid().clone(),
            goal: self.goal.as_ref().and_then(in_flight).map(Box::new),
            ended: ended.map(|e| Box::new(e.goal.clone())),
        });
        match ctx.answer(&mut query, Performative::Inform, &answer) {
            Ok(()) => {
                if let (Some(e), Some(q)) = (self.ended.as_mut(), querier)
                    && e.told.len() < ENDED_TOLD_MAX
                {
                    e.told.insert(q);
                }
            }
            Err(err) => {
                tracing::warn!(chair = %self.config.chair, error = %err, "could not answer a goal query")
            }
        }
    }

    fn on_answer(&mut self, ctx: &mut Context<'_>, message: &AclMessage) {
        let conversation = message.conversation_id.clone().unwrap_or_default();
        let performative = message.performative;
        if let Some(answer) = self.releasing.handle(ctx, message) {
            self.on_release_answer(answer, message);
            return;
        }
        if let Some(answer) = self.held.handle(ctx, message) {
            // Only a FAILURE (the lease ran out while the chair is still on its way) can end a
            // held grant from the watcher's side; the chair lets go by itself otherwise.
            if let Ok(Progress::Ended(event, passage)) = answer {
                tracing::warn!(chair = %self.config.chair, %passage, kind = ?event.kind, "the watcher took the passage back");
            }
            return;
        }
        let (kind, waiting) = match self.pending.handle(ctx, message) {
            None => {
                tracing::debug!(%conversation, "answer to an abandoned step");
                return;
            }
            Some(Err(err)) => {
                tracing::debug!(error = %err, "out-of-protocol answer; ignored");
                return;
            }
            Some(Ok(Progress::Continues(event))) => {
                self.on_pass_progress(ctx, &conversation, event.kind);
                return;
            }
            Some(Ok(Progress::Ended(event, waiting))) => (event.kind, waiting),
        };
        let done = kind == EventKind::Informed;
        match waiting {
            Waiting::Door { door } if done => {
                self.open_doors.insert(door);
                self.advance(ctx);
            }
            Waiting::Door { door } => {
                tracing::info!(door = %door, answer = %performative, "door not opened; re-planning");
                self.locked_doors.insert(door);
                self.replan(ctx);
            }
            Waiting::Drive { motion } if done => {
                self.release_reached(ctx, |_| true);
                self.next_leg(ctx, motion)
            }
            Waiting::Drive { motion } => {
                if let Ok(WheelchairContent::Inform(Fact::BodyFault { reason })) =
                    WheelchairContent::from_message(message)
                {
                    tracing::info!(chair = %self.config.chair, from = %motion.from, to = %motion.to, %reason, "the body failed the motion");
                    self.finish(ctx, Err(format!("the chair's body failed: {reason}")));
                    return;
                }
                let why = message.content_text().unwrap_or_default();
                tracing::info!(chair = %self.config.chair, from = %motion.from, to = %motion.to, answer = %performative, why, "motion failed; re-planning");
                self.blocked.insert((motion.from, motion.to));
                self.replan(ctx);
            }
            Waiting::Pass {
                motion, passage, ..
            } => {
                tracing::warn!(passage = %passage, answer = %performative, "the watcher does not keep this passage; going on");
                self.next_leg(ctx, motion);
            }
        }
    }

    /// The watcher's answer to a CANCEL of a passage: the confirmation, told by its content
    /// from a grant that crossed the CANCEL (the watcher lets go on the CANCEL all the same),
    /// or a FAILURE to cancel.
    fn on_release_answer(
        &mut self,
        answer: Result<Progress<Releasing>, iw_agent::AgentError>,
        message: &AclMessage,
    ) {
        let chair = &self.config.chair;
        match answer {
            Ok(Progress::Ended(event, Releasing { passage, .. })) => {
                match (event.kind, WheelchairContent::from_message(message)) {
                    (EventKind::Cancelled, Ok(WheelchairContent::Cancelled { .. })) => {
                        tracing::debug!(%chair, %passage, "the watcher confirmed the release");
                    }
                    (EventKind::Cancelled, Ok(WheelchairContent::Done { .. })) => {
                        tracing::debug!(%chair, %passage, "a grant crossed the release; the watcher lets go on the CANCEL");
                    }
                    (kind, content) => {
                        tracing::warn!(%chair, %passage, ?kind, content = ?content.ok(), "the watcher did not confirm the release");
                    }
                }
            }
            Ok(Progress::Continues(event)) => {
                tracing::debug!(%chair, kind = ?event.kind, "an answer while releasing a passage");
            }
            Err(err) => {
                tracing::debug!(%chair, error = %err, "out-of-protocol answer to a release; ignored")
            }
        }
    }

    /// An AGREE or a notification in the subscription of the passage waited for: the chair is
    /// queued, or granted the passage, which is then held (its subscription kept) as it drives
    /// through.
    fn on_pass_progress(&mut self, ctx: &mut Context<'_>, conversation: &str, kind: EventKind) {
        let Some(Waiting::Pass {
            passage, agreed, ..
        }) = self.pending.get_mut(conversation)
        else {
            return;
        };
        if kind != EventKind::Notified {
            *agreed = true;
            return;
        }
        let passage = passage.clone();
        let Some(Waiting::Pass { motion, .. }) =
            self.pending
                .hand_over(conversation, &mut self.held, passage.clone())
        else {
            return;
        };
        tracing::info!(chair = %self.config.chair, passage = %passage, "passage granted");
        self.next_leg(ctx, motion);
    }

    /// A pose at (`x_m`, `y_m`) whose variance in its worst direction is `uncertainty_m2`.
    fn on_pose(&mut self, ctx: &mut Context<'_>, x_m: f64, y_m: f64, uncertainty_m2: f64) {
        let here = Point2::new(x_m, y_m);
        self.t_map_base = Some(here);
        tracing::trace!(chair = %self.config.chair, t_s = ctx.now().0 as f64 * 1e-9, x_m, y_m, worst_variance_m2 = uncertainty_m2, "pose");
        self.release_reached(ctx, |at| (at - here).norm() <= RELEASE_RADIUS_M);
        let was_below = !self.too_uncertain();
        self.uncertainty_m2 = uncertainty_m2;
        // the uncertainty counts from its lowest since the last landmark (a marker's reading
        // lowers it on the way in, and at the stop)
        self.uncertainty_at_landmark_m2 = self.uncertainty_at_landmark_m2.min(uncertainty_m2);
        let at_landmark = self.pending.iter().find_map(|(id, waiting)| match waiting {
            Waiting::Drive { motion } => motion
                .landmark
                .filter(|at| (at - here).norm() <= RELEASE_RADIUS_M)
                .map(|at| (id.to_string(), at)),
            _ => None,
        });
        if let Some((id, at)) = at_landmark {
            if let Some(Waiting::Drive { motion }) = self.pending.get_mut(&id) {
                motion.landmark = None;
            }
            self.landmark_visited(at);
        }
        if was_below && self.too_uncertain() {
            tracing::info!(chair = %self.config.chair, worst_variance_m2 = uncertainty_m2, at_landmark_m2 = self.uncertainty_at_landmark_m2, "pose too uncertain");
            self.detour(ctx);
        }
    }

    /// Whether the uncertainty grew past [`CognitiveConfig::uncertainty_m2`] since the last
    /// landmark.
    fn too_uncertain(&self) -> bool {
        self.uncertainty_m2 - self.uncertainty_at_landmark_m2 > self.config.uncertainty_m2
    }

    /// The chair got to the landmark stop `at`: the uncertainty counts from here (and from
    /// lower, once the marker is read), a dropped laser's debt is paid, and the next detour goes
    /// elsewhere.
    fn landmark_visited(&mut self, at: Point2<f64>) {
        self.uncertainty_at_landmark_m2 = self.uncertainty_m2;
        self.landmark_owed = false;
        self.last_landmark = Some(at);
    }

    /// The landmarks a detour may go to: all but the one visited last.
    fn detour_landmarks(&self) -> impl Iterator<Item = &LandmarkStop> {
        self.config
            .map
            .landmarks
            .iter()
            .filter(|l| Some(l.at) != self.last_landmark)
    }

    /// Re-issues the drive under way via a landmark, unless it goes past one already
    /// (or the map has none but the one visited last).
    fn detour(&mut self, ctx: &mut Context<'_>) {
        let driving = self.pending.iter().find_map(|(_, waiting)| match waiting {
            Waiting::Drive { motion } if motion.landmark.is_none() => Some(motion.clone()),
            _ => None,
        });
        if let Some(Motion { from, to, door, .. }) = driving
            && self.detour_landmarks().next().is_some()
        {
            tracing::info!(chair = %self.config.chair, "detouring via a landmark");
            self.motion(ctx, from, to, door);
        }
    }

    /// The perception agent dropped a range sensor or took it back: a silent laser owes the
    /// chair a landmark visit, starting with the drive under way.
    fn on_sensor(&mut self, ctx: &mut Context<'_>, state: SensorState) {
        if state.sensor != "laser" {
            return;
        }
        match state.usage {
            SensorUse::Dropped if !self.landmark_owed => {
                tracing::warn!(chair = %self.config.chair, reason = %state.reason, "the laser was dropped: the chair dead-reckons");
                self.landmark_owed = true;
                self.detour(ctx);
            }
            SensorUse::Dropped => {}
            SensorUse::InUse => {
                tracing::info!(chair = %self.config.chair, "the laser is back");
                self.landmark_owed = false;
            }
        }
    }
}

/// The variance of `pose`'s position in its worst direction, m²: the larger eigenvalue of its
/// x-y covariance (of its symmetric part, should a sender's be not quite symmetric). In closed
/// form, so that no input (a NaN) can keep an iterative solver going; NaN in, NaN out, which
/// compares as no detour.
pub fn worst_variance_m2(pose: &Pose) -> f64 {
    let c = &pose.covariance;
    let (xx, yy, xy) = (c[(0, 0)], c[(1, 1)], 0.5 * (c[(0, 1)] + c[(1, 0)]));
    0.5 * (xx + yy) + (0.5 * (xx - yy)).hypot(xy)
}

/// Why a goal ends when a newer one comes.
const REPLACED: &str = "replaced by a newer goal";

/// `goal` as a goal query tells it (under way).
fn in_flight(goal: &Goal) -> Option<GoalInFlight> {
    Some(GoalInFlight {
        place: goal.place.clone(),
        requester: goal.responder.initiator()?.clone(),
        conversation: goal.responder.conversation_id().to_string(),
        outcome: None,
    })
}

impl Agent for CognitiveAgent {
    fn setup(&mut self, ctx: &mut Context<'_>) {
        if let Some(perception) = self.config.perception.clone() {
            let subscribe = Subscription::to([Topic::AtPose]).fill(
                AclMessage::new(Performative::Subscribe)
                    .with_receiver(perception)
                    .with_conversation_id(format!("pose-{}", ctx.name())),
            );
            if let Err(err) = self.poses.open(ctx, Protocol::Subscribe, subscribe, ()) {
                tracing::warn!(error = %err, "could not subscribe to the chair's pose");
            }
        }
    }

    fn tick_period(&self) -> Option<Duration> {
        self.config
            .watcher
            .as_ref()
            .map(|_| Duration::from_millis(200))
    }

    /// Gives up waiting for a watcher that does not answer or does not grant in time, or that
    /// does not confirm a release.
    fn tick(&mut self, ctx: &mut Context<'_>) {
        let now_ns = ctx.now().0;
        let overdue: Vec<String> = self
            .releasing
            .iter()
            .filter(|(_, r)| {
                Duration::from_nanos(now_ns.saturating_sub(r.since_ns)) >= CANCEL_CONFIRM_TIMEOUT
            })
            .map(|(id, _)| id.to_owned())
            .collect();
        for id in overdue {
            if let Some(r) = self.releasing.forget(&id) {
                tracing::warn!(chair = %self.config.chair, passage = %r.passage, conversation = %id, "no confirmation of the release from the watcher; the passage was let go all the same");
            }
        }
        let Some(Waiting::Pass {
            motion,
            passage,
            asked_ns,
            agreed,
        }) = self
            .pending
            .iter()
            .next()
            .map(|(_, waiting)| waiting.clone())
        else {
            return;
        };
        let waited = Duration::from_nanos(ctx.now().0.saturating_sub(asked_ns));
        if (agreed || waited < PASS_ANSWER_TIMEOUT) && waited < self.config.pass_wait {
            return;
        }
        tracing::warn!(chair = %self.config.chair, passage = %passage, agreed, waited_s = waited.as_secs_f64(), "no grant from the watcher; going on");
        self.abandon(ctx);
        self.next_leg(ctx, motion);
    }

    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        match self.poses.handle(ctx, &message) {
            Some(Ok(Progress::Continues(event))) if event.kind == EventKind::Notified => {
                match WheelchairContent::from_message(&message) {
                    Ok(WheelchairContent::Inform(Fact::AtPose { pose, .. })) => {
                        let was_localized =
                            std::mem::replace(&mut self.localized, pose.localized());
                        if !self.localized {
                            if was_localized {
                                tracing::warn!(chair = %self.config.chair, "the chair lost its pose: goals are refused until it finds itself");
                                self.finish(ctx, Err("the chair lost its pose on the map".into()));
                            }
                            return;
                        }
                        let worst = worst_variance_m2(&pose);
                        self.on_pose(ctx, pose.x_m, pose.y_m, worst)
                    }
                    Ok(WheelchairContent::Inform(Fact::Sensor { state, .. })) => {
                        self.on_sensor(ctx, state)
                    }
                    Ok(_) => {}
                    Err(err) => tracing::debug!(error = %err, "ignored a pose notification"),
                }
                return;
            }
            Some(Ok(Progress::Continues(_))) => return,
            Some(Ok(Progress::Ended(event, ()))) => {
                tracing::warn!(chair = %self.config.chair, kind = ?event.kind, "the pose subscription ended");
                return;
            }
            Some(Err(err)) => {
                tracing::debug!(error = %err, "out-of-protocol pose message");
                return;
            }
            None => {}
        }
        match message.performative {
            Performative::Request => match WheelchairContent::from_message(&message) {
                Ok(WheelchairContent::Request {
                    actor,
                    action: WheelchairAction::GoTo { place },
                }) => self.on_goal(ctx, message, actor, place),
                Ok(_) => {
                    let _ = ctx.refuse(&message, "the cognitive agent takes go-to goals");
                }
                Err(err) => {
                    let _ = ctx.not_understood(&message, &err.to_string());
                }
            },
            Performative::QueryRef => self.on_query(ctx, &message),
            act if answers_a_conversation(act) => self.on_answer(ctx, &message),
            _ => {
                let _ = ctx.not_understood(
                    &message,
                    "the cognitive agent takes go-to requests, goal queries, poses and answers",
                );
            }
        }
    }
}

/// CANCEL of subscription `id` (a passage released, or given up while queued); the
/// conversation moves to `releasing`, where the watcher's confirmation ends it.
fn cancel<T>(
    ctx: &mut Context<'_>,
    conversations: &mut Initiated<T>,
    releasing: &mut Initiated<Releasing>,
    id: &str,
    passage: &str,
) {
    if let Err(err) = conversations.cancel(ctx, id) {
        tracing::warn!(error = %err, conversation = id, "could not cancel the passage");
        conversations.forget(id);
        return;
    }
    let waiting = Releasing {
        passage: passage.to_owned(),
        since_ns: ctx.now().0,
    };
    conversations.hand_over(id, releasing, waiting);
}
