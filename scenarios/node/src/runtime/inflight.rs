//! Goals in flight the services do not follow: when a chair joins (after a restart of the
//! services, or of the chair's link), its cognitive agent is asked for the goal it carries out
//! and the last one that ended. A goal given by an earlier life of the services, through the
//! assistant by a foreign platform, or at the chair itself would otherwise end where no one here
//! hears it: one under way is given again by the services (who then follow it) or, when their
//! own goal for the chair replaces it, reported failed; one that ended meanwhile is reported
//! with its outcome. Each time a `goal` event says which, with the reason and the requester.

use iw_ontology::wheelchair::GoalInFlight;
use iw_wiring::GoalAnswer;

use super::ServiceDesk;
use crate::Event;

/// How often a chair that does not answer is asked again before the services give up (and say
/// so in the log).
pub(super) const GOAL_QUERY_ATTEMPTS: u32 = 3;

/// What becomes of a goal a chair says it carries out.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Verdict {
    /// The services follow it (their assistant gave it, and they have a goal for the chair).
    Followed,
    /// The services' own goal for the chair replaces it: reported failed, with the reason.
    Replaced(Event),
    /// No one here follows it: reported failed in its old conversation, with the reason, and
    /// given again by the services.
    GivenAgain(Event),
    /// It ended where no one here heard it: reported with its outcome.
    Ended(Event),
}

/// Judges `chair`'s goal under way: `ours` whether the services have a goal given or waiting
/// for the chair, `assistant` their assistant's name.
pub(super) fn judge(chair: &str, goal: GoalInFlight, ours: bool, assistant: &str) -> Verdict {
    let requester = goal.requester.name;
    let from_us = requester == assistant;
    if ours && from_us {
        return Verdict::Followed;
    }
    let was = format!(
        "{chair} was going to {} for {requester} (conversation {})",
        goal.place, goal.conversation
    );
    if let Some(outcome) = goal.outcome {
        let (performative, reason) = match outcome {
            Ok(()) => ("INFORM", None),
            Err(why) => (
                "FAILURE",
                Some(format!(
                    "{was}; it failed where these services did not hear it: {why}"
                )),
            ),
        };
        return Verdict::Ended(Event::Goal {
            chair: chair.to_string(),
            place: goal.place,
            conversation: goal.conversation,
            performative: performative.into(),
            reason,
            requester: Some(requester),
        });
    }
    let (reason, verdict): (_, fn(Event) -> Verdict) = if ours {
        (
            format!("{was}; the services' own goal for {chair} replaces it"),
            Verdict::Replaced,
        )
    } else {
        (
            format!(
                "{was}, a goal these services do not follow (they restarted, or it was given \
                 past them): given again by the services, who follow it from here"
            ),
            Verdict::GivenAgain,
        )
    };
    verdict(Event::Goal {
        chair: chair.to_string(),
        place: goal.place,
        conversation: goal.conversation,
        performative: "FAILURE".into(),
        reason: Some(reason),
        requester: Some(requester),
    })
}

impl ServiceDesk {
    /// Whether the services have a goal for `chair`, given or waiting.
    fn has_goal_for(&self, chair: &str) -> bool {
        self.given.values().any(|(c, _)| c == chair) || self.waiting.iter().any(|(c, _)| c == chair)
    }

    /// Takes `chair`'s answer to the query for its goal: the events to report; a goal under way
    /// no one follows is put among the waiting goals, and a silent chair still `present` is
    /// asked again (up to [`GOAL_QUERY_ATTEMPTS`] times).
    pub(super) fn take_goal_answer(
        &mut self,
        chair: String,
        answer: GoalAnswer,
        present: bool,
        assistant: &str,
    ) -> Vec<Event> {
        let goals = match answer {
            GoalAnswer::Told { goal, ended } => {
                self.goal_asked.remove(&chair);
                ended.into_iter().chain(goal)
            }
            GoalAnswer::Silent if present => {
                let asked = self.goal_asked.entry(chair.clone()).or_insert(1);
                if *asked < GOAL_QUERY_ATTEMPTS {
                    *asked += 1;
                    iw_wiring::desk(&self.desk).goal_queries.insert(chair);
                } else {
                    tracing::warn!(%chair, attempts = *asked, "the chair never said which goal it carries out: a goal given to it past these services is not followed");
                }
                return Vec::new();
            }
            GoalAnswer::Silent => return Vec::new(),
            GoalAnswer::Unusable(why) => {
                tracing::warn!(%chair, %why, "the chair could not say which goal it carries out: a goal given to it past these services is not followed");
                return Vec::new();
            }
        };
        let mut events = Vec::new();
        for goal in goals {
            let ours = self.has_goal_for(&chair);
            match judge(&chair, *goal, ours, assistant) {
                Verdict::Followed => {}
                Verdict::Replaced(event) | Verdict::Ended(event) => events.push(event),
                Verdict::GivenAgain(event) => {
                    if let Event::Goal { place, .. } = &event {
                        self.waiting.push((chair.clone(), place.clone()));
                    }
                    events.push(event);
                }
            }
        }
        events
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use iw_acl::AgentId;

    fn goal(requester: &str) -> GoalInFlight {
        GoalInFlight {
            place: "dining-hall".into(),
            requester: AgentId::new(requester),
            conversation: "c-7".into(),
            outcome: None,
        }
    }

    fn reason(verdict: &Verdict) -> String {
        match verdict {
            Verdict::Replaced(Event::Goal { reason, .. })
            | Verdict::GivenAgain(Event::Goal { reason, .. }) => reason.clone().unwrap(),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_goal_no_one_follows_is_given_again_and_one_replaced_is_failed_both_with_the_reason() {
        let assistant = "assistant@services";
        assert_eq!(
            judge("chair-a", goal(assistant), true, assistant),
            Verdict::Followed
        );
        // An earlier life of the services gave it: no goal here for the chair.
        let again = judge("chair-a", goal(assistant), false, assistant);
        assert!(matches!(again, Verdict::GivenAgain(_)), "{again:?}");
        let why = reason(&again);
        assert!(
            why.contains("chair-a was going to dining-hall for assistant@services")
                && why.contains("c-7")
                && why.contains("given again"),
            "{why}"
        );
        let Verdict::GivenAgain(Event::Goal {
            performative,
            requester,
            conversation,
            ..
        }) = again
        else {
            unreachable!()
        };
        assert_eq!(
            (
                performative.as_str(),
                requester.as_deref(),
                conversation.as_str()
            ),
            ("FAILURE", Some(assistant), "c-7")
        );
        // The chair's own interface gave it, and the services have a goal for the chair.
        let replaced = judge("chair-a", goal("interface@chair-a"), true, assistant);
        assert!(matches!(replaced, Verdict::Replaced(_)), "{replaced:?}");
        assert!(reason(&replaced).contains("replaces it"));
        let again = judge("chair-a", goal("interface@chair-a"), false, assistant);
        assert!(matches!(again, Verdict::GivenAgain(_)), "{again:?}");
        // One that ended where no one here heard it is reported with its outcome.
        let failed = GoalInFlight {
            outcome: Some(Err("the chair's body failed".into())),
            ..goal(assistant)
        };
        let ended = judge("chair-a", failed, false, assistant);
        let Verdict::Ended(Event::Goal {
            performative,
            reason,
            ..
        }) = &ended
        else {
            panic!("{ended:?}")
        };
        assert_eq!(performative, "FAILURE");
        assert!(
            reason
                .as_deref()
                .unwrap()
                .ends_with("the chair's body failed")
        );
        let reached = GoalInFlight {
            outcome: Some(Ok(())),
            ..goal(assistant)
        };
        assert!(matches!(
            judge("chair-a", reached, false, assistant),
            Verdict::Ended(Event::Goal { ref performative, .. }) if performative == "INFORM"
        ));
    }
}
