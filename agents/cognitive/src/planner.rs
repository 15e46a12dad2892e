//! Grounds a [`Domain`] and [`Problem`] and finds the shortest plan by breadth-first search.
//!
//! Grounding binds each schema's parameters to every type-compatible object and drops the
//! bindings whose static preconditions (predicates no action changes) are false initially, which
//! keeps building-sized problems (tens of places, a few chairs and doors) to a few thousand
//! ground actions. States are bit sets over the ground atoms.

use std::collections::{HashMap, HashSet, VecDeque};

use crate::pddl::{Atom, Domain, Literal, Problem, Term};

/// One ground action of a plan: the schema name and its arguments.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Step {
    /// Action name.
    pub action: String,
    /// Object names bound to its parameters, in order.
    pub args: Vec<String>,
}

impl std::fmt::Display for Step {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "({}", self.action)?;
        for a in &self.args {
            write!(f, " {a}")?;
        }
        f.write_str(")")
    }
}

/// A sequence of intermediate objectives.
pub type Plan = Vec<Step>;

/// Why no plan was returned.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum PlanError {
    /// Every reachable state was explored: the goal cannot be reached.
    #[error("the goal cannot be reached from the initial state ({explored} states explored)")]
    Unreachable {
        /// States explored.
        explored: usize,
    },
    /// The search stopped at its state budget.
    #[error(
        "search stopped after {limit} states without reaching the goal; raise the limit or simplify the problem"
    )]
    LimitReached {
        /// The budget.
        limit: usize,
    },
    /// An object or constant used in the problem is not declared.
    #[error("`{name}` is used but not declared as an object or constant")]
    UnknownObject {
        /// The name.
        name: String,
    },
}

struct GroundAction {
    step: Step,
    pre_pos: Vec<usize>,
    pre_neg: Vec<usize>,
    add: Vec<usize>,
    del: Vec<usize>,
}

#[derive(Default)]
struct Atoms {
    ids: HashMap<(String, Vec<String>), usize>,
}

impl Atoms {
    fn id(&mut self, predicate: &str, args: Vec<String>) -> usize {
        let next = self.ids.len();
        *self
            .ids
            .entry((predicate.to_string(), args))
            .or_insert(next)
    }
}

type State = Vec<u64>;

fn has(state: &State, id: usize) -> bool {
    state
        .get(id / 64)
        .is_some_and(|w| w & (1 << (id % 64)) != 0)
}

fn set(state: &mut State, id: usize, on: bool) {
    if state.len() <= id / 64 {
        state.resize(id / 64 + 1, 0);
    }
    if on {
        state[id / 64] |= 1 << (id % 64);
    } else {
        state[id / 64] &= !(1 << (id % 64));
    }
}

/// Finds a shortest plan, exploring at most `max_states` states.
pub fn plan(domain: &Domain, problem: &Problem, max_states: usize) -> Result<Plan, PlanError> {
    let objects: Vec<(String, String)> = domain
        .constants
        .iter()
        .chain(&problem.objects)
        .cloned()
        .collect();
    let declared: HashSet<&str> = objects.iter().map(|(n, _)| n.as_str()).collect();
    let ground_args = |atom: &Atom| -> Result<Vec<String>, PlanError> {
        atom.args
            .iter()
            .map(|t| match t {
                Term::Const(c) if declared.contains(c.as_str()) => Ok(c.clone()),
                Term::Const(c) | Term::Var(c) => Err(PlanError::UnknownObject { name: c.clone() }),
            })
            .collect()
    };
    let mut atoms = Atoms::default();
    let mut init = State::new();
    let mut init_set: HashSet<(String, Vec<String>)> = HashSet::new();
    for a in &problem.init {
        let args = ground_args(a)?;
        init_set.insert((a.predicate.clone(), args.clone()));
        let id = atoms.id(&a.predicate, args);
        set(&mut init, id, true);
    }
    let mut goal = Vec::new();
    for l in &problem.goal {
        let id = atoms.id(&l.atom.predicate, ground_args(&l.atom)?);
        goal.push((id, l.positive));
    }
    let dynamic: HashSet<&str> = domain
        .actions
        .iter()
        .flat_map(|a| a.add.iter().chain(&a.delete))
        .map(|a| a.predicate.as_str())
        .collect();

    let mut actions = Vec::new();
    for schema in &domain.actions {
        let candidates: Vec<Vec<&str>> = schema
            .parameters
            .iter()
            .map(|(_, ty)| {
                objects
                    .iter()
                    .filter(|(_, oty)| domain.is_subtype(oty, ty))
                    .map(|(n, _)| n.as_str())
                    .collect()
            })
            .collect();
        let mut binding = vec![0usize; candidates.len()];
        if candidates.iter().any(Vec::is_empty) {
            continue;
        }
        'bindings: loop {
            let values: HashMap<&str, &str> = schema
                .parameters
                .iter()
                .zip(&binding)
                .zip(&candidates)
                .map(|(((var, _), &i), c)| (var.as_str(), c[i]))
                .collect();
            let bind = |atom: &Atom| -> Vec<String> {
                atom.args
                    .iter()
                    .map(|t| match t {
                        Term::Var(v) => values
                            .get(v.as_str())
                            .map_or_else(|| v.clone(), |s| s.to_string()),
                        Term::Const(c) => c.clone(),
                    })
                    .collect()
            };
            let statically_ok = schema
                .precondition
                .iter()
                .all(|Literal { positive, atom }| {
                    dynamic.contains(atom.predicate.as_str())
                        || init_set.contains(&(atom.predicate.clone(), bind(atom))) == *positive
                });
            if statically_ok {
                let mut ids = |list: &mut dyn Iterator<Item = &Atom>| -> Vec<usize> {
                    list.map(|a| atoms.id(&a.predicate, bind(a))).collect()
                };
                let dynamic = &dynamic;
                let dynamic_pre = |positive: bool| {
                    schema
                        .precondition
                        .iter()
                        .filter(move |l| {
                            l.positive == positive && dynamic.contains(l.atom.predicate.as_str())
                        })
                        .map(|l| &l.atom)
                };
                actions.push(GroundAction {
                    step: Step {
                        action: schema.name.clone(),
                        args: binding
                            .iter()
                            .zip(&candidates)
                            .map(|(&i, c)| c[i].to_string())
                            .collect(),
                    },
                    pre_pos: ids(&mut dynamic_pre(true)),
                    pre_neg: ids(&mut dynamic_pre(false)),
                    add: ids(&mut schema.add.iter()),
                    del: ids(&mut schema.delete.iter()),
                });
            }
            for (slot, c) in binding.iter_mut().zip(&candidates).rev() {
                *slot += 1;
                if *slot < c.len() {
                    continue 'bindings;
                }
                *slot = 0;
            }
            break;
        }
    }

    let is_goal = |s: &State| goal.iter().all(|&(id, positive)| has(s, id) == positive);
    let normalize = |mut s: State| {
        while s.last() == Some(&0) {
            s.pop();
        }
        s
    };
    let init = normalize(init);
    let mut parent: HashMap<State, Option<(State, usize)>> = HashMap::new();
    parent.insert(init.clone(), None);
    let mut frontier = VecDeque::from([init]);
    while let Some(state) = frontier.pop_front() {
        if is_goal(&state) {
            let mut plan = Vec::new();
            let mut cursor = state;
            while let Some(Some((prev, action))) = parent.get(&cursor) {
                plan.push(actions[*action].step.clone());
                cursor = prev.clone();
            }
            plan.reverse();
            return Ok(plan);
        }
        for (index, a) in actions.iter().enumerate() {
            if a.pre_pos.iter().all(|&id| has(&state, id))
                && a.pre_neg.iter().all(|&id| !has(&state, id))
            {
                let mut next = state.clone();
                for &id in &a.del {
                    set(&mut next, id, false);
                }
                for &id in &a.add {
                    set(&mut next, id, true);
                }
                let next = normalize(next);
                if !parent.contains_key(&next) {
                    if parent.len() >= max_states {
                        return Err(PlanError::LimitReached { limit: max_states });
                    }
                    parent.insert(next.clone(), Some((state.clone(), index)));
                    frontier.push_back(next);
                }
            }
        }
    }
    Err(PlanError::Unreachable {
        explored: parent.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOMAIN: &str = include_str!("../domains/building.pddl");

    fn problem(init_extra: &str, goal: &str) -> Problem {
        let text = format!(
            "(define (problem p) (:domain building)
               (:objects chair1 - chair bedroom corridor hall dining - place d1 d2 - door)
               (:init (at chair1 bedroom)
                      (connected bedroom corridor) (connected corridor bedroom)
                      (connected corridor hall) (connected hall corridor)
                      (through corridor dining d1) (through dining corridor d1)
                      (through hall dining d2) (through dining hall d2)
                      {init_extra})
               (:goal {goal}))"
        );
        Problem::parse(&text, &Domain::parse(DOMAIN).unwrap()).unwrap()
    }

    #[test]
    fn shortest_plan_opens_the_nearest_door() {
        let domain = Domain::parse(DOMAIN).unwrap();
        let plan = plan(&domain, &problem("", "(at chair1 dining)"), 10_000).unwrap();
        let text: Vec<String> = plan.iter().map(Step::to_string).collect();
        assert_eq!(
            text,
            [
                "(move chair1 bedroom corridor)",
                "(open-door chair1 corridor dining d1)",
                "(pass-door chair1 corridor dining d1)",
            ]
        );
    }

    #[test]
    fn a_locked_door_is_routed_around() {
        let domain = Domain::parse(DOMAIN).unwrap();
        let plan = plan(
            &domain,
            &problem("(locked d1)", "(at chair1 dining)"),
            10_000,
        )
        .unwrap();
        assert!(
            plan.iter().all(|s| !s.args.contains(&"d1".to_string())),
            "{plan:?}"
        );
        assert_eq!(
            plan.last().unwrap().to_string(),
            "(pass-door chair1 hall dining d2)"
        );
    }

    #[test]
    fn unreachable_goal_is_reported() {
        let domain = Domain::parse(DOMAIN).unwrap();
        let err = plan(
            &domain,
            &problem("(locked d1) (locked d2)", "(at chair1 dining)"),
            10_000,
        )
        .unwrap_err();
        assert!(matches!(err, PlanError::Unreachable { .. }), "{err}");
        let err = plan(
            &domain,
            &problem("(locked d1) (locked d2)", "(at chair1 dining)"),
            2,
        )
        .unwrap_err();
        assert_eq!(err, PlanError::LimitReached { limit: 2 });
    }

    #[test]
    fn undeclared_objects_are_named() {
        let domain = Domain::parse(DOMAIN).unwrap();
        let mut p = problem("", "(at chair1 dining)");
        p.goal[0].atom.args[1] = Term::Const("kitchen".into());
        assert_eq!(
            plan(&domain, &p, 100),
            Err(PlanError::UnknownObject {
                name: "kitchen".into()
            })
        );
    }
}
