//! The cognitive agent's strategic layer (thesis 3.3.2, figure 3.2): goal planning with a
//! PDDL-subset planner, then path planning with A* on the world model.
//!
//! Organization:
//! - [`agent`]: the cognitive agent on the bus ([`agent::CognitiveAgent`]), its messages and
//!   its building map.
//! - [`pddl`]: reads STRIPS domains and problems written in PDDL (`:strips`, `:typing`,
//!   `:negative-preconditions`) into [`Domain`] and [`Problem`].
//! - [`planner`]: grounds them and searches for the shortest plan of intermediate objectives.
//! - [`passage`]: cuts a path into legs at narrow passages, which the watcher agent grants one
//!   direction at a time.
//! - [`grid`]: [`OccupancyGrid`] and A* between metric points, with obstacles inflated by the
//!   chair's radius.
//!
//! Guarantees: parsing never panics and reports line and column; a returned plan is valid (each
//! action applicable in turn, goal true at the end) and shortest in number of actions; a returned
//! path only crosses free cells and is the cheapest 8-connected path.
#![warn(missing_docs)]

pub mod agent;
pub mod grid;
pub mod passage;
pub mod pddl;
pub mod planner;

pub use grid::{GridError, OccupancyGrid, Path2};
pub use passage::{Leg, NarrowPassage};
pub use pddl::{Domain, PddlError, Problem};
pub use planner::{Plan, PlanError, Step, plan};
