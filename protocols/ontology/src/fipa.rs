//! FIPA-Agent-Management (SC00023): what agents say to the AMS and the DF, as typed values.
//!
//! Slot order follows JADE's ontology so that re-encoding JADE's answers gives JADE's text.

use iw_acl::AgentId;
use iw_sl::{
    ActionExpression, Arguments, Collection, Content, ContentExpression, DateTime, Formula,
    IdentifyingExpression, Level, ReferentialOp, Term,
};
use serde::{Deserialize, Serialize};

use crate::concept::{
    Concept, Frame, FrameBuilder, is_frame, shown, text_of, word_enum, word_value,
};
use crate::error::OntologyError;

/// The `:ontology` name of this ontology.
pub const ONTOLOGY: &str = "FIPA-Agent-Management";

impl Concept for AgentId {
    fn to_term(&self) -> Term {
        let mut b = FrameBuilder::new("agent-identifier")
            .text("name", Some(&self.name))
            .texts("addresses", Collection::Sequence, &self.addresses)
            .concepts("resolvers", Collection::Sequence, &self.resolvers);
        for (key, value) in &self.user_params {
            b = b.term(&format!("X-{key}"), Term::string(value.as_str()));
        }
        b.build()
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        let f = Frame::read(term, "agent-identifier")?;
        let mut aid = AgentId::new(f.required_text("name")?);
        for address in f.texts("addresses")? {
            aid = aid.with_address(address);
        }
        for resolver in f.concepts::<AgentId>("resolvers")? {
            aid = aid.with_resolver(resolver);
        }
        for p in f.user_slots() {
            let value = text_of(&p.value).ok_or_else(|| OntologyError::BadValue {
                concept: "agent-identifier",
                slot: "X-",
                value: shown(&p.value),
                reason: "user-defined slots hold words or strings",
            })?;
            aid = aid.with_user_param(&p.name, value);
        }
        Ok(aid)
    }
}

/// `(property :name n :value v)`: a service property; the value is any SL term.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Property {
    /// Property name, e.g. `max-speed`.
    pub name: String,
    /// Its value, e.g. the float `1.5`.
    pub value: Term,
}

impl Concept for Property {
    fn to_term(&self) -> Term {
        FrameBuilder::new("property")
            .text("name", Some(&self.name))
            .term("value", self.value.clone())
            .build()
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        let f = Frame::read(term, "property")?;
        Ok(Self {
            name: f.required_text("name")?,
            value: f.require("value")?.clone(),
        })
    }
}

/// `(service-description ...)`: a service an agent offers through the DF. Every slot is optional
/// (a search template sets only those to match).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ServiceDescription {
    /// `:name`
    pub name: Option<String>,
    /// `:type`, e.g. `wheelchair-navigation`.
    pub service_type: Option<String>,
    /// `:protocols` (set).
    pub protocols: Vec<String>,
    /// `:ontologies` (set).
    pub ontologies: Vec<String>,
    /// `:languages` (set).
    pub languages: Vec<String>,
    /// `:ownership`
    pub ownership: Option<String>,
    /// `:properties` (set).
    pub properties: Vec<Property>,
}

impl Concept for ServiceDescription {
    fn to_term(&self) -> Term {
        FrameBuilder::new("service-description")
            .text("name", self.name.as_deref())
            .text("type", self.service_type.as_deref())
            .texts("protocols", Collection::Set, &self.protocols)
            .texts("ontologies", Collection::Set, &self.ontologies)
            .texts("languages", Collection::Set, &self.languages)
            .text("ownership", self.ownership.as_deref())
            .concepts("properties", Collection::Set, &self.properties)
            .build()
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        let f = Frame::read(term, "service-description")?;
        Ok(Self {
            name: f.text("name")?,
            service_type: f.text("type")?,
            protocols: f.texts("protocols")?,
            ontologies: f.texts("ontologies")?,
            languages: f.texts("languages")?,
            ownership: f.text("ownership")?,
            properties: f.concepts("properties")?,
        })
    }
}

/// `(df-agent-description ...)`: an agent's entry in the yellow pages.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DfAgentDescription {
    /// `:name`: the agent (absent in search templates).
    pub name: Option<AgentId>,
    /// `:services` (set).
    pub services: Vec<ServiceDescription>,
    /// `:protocols` (set).
    pub protocols: Vec<String>,
    /// `:ontologies` (set).
    pub ontologies: Vec<String>,
    /// `:languages` (set).
    pub languages: Vec<String>,
    /// `:lease-time`: when the registration expires.
    pub lease_time: Option<DateTime>,
}

impl Concept for DfAgentDescription {
    fn to_term(&self) -> Term {
        FrameBuilder::new("df-agent-description")
            .opt_term("name", self.name.as_ref().map(Concept::to_term))
            .concepts("services", Collection::Set, &self.services)
            .texts("protocols", Collection::Set, &self.protocols)
            .texts("ontologies", Collection::Set, &self.ontologies)
            .texts("languages", Collection::Set, &self.languages)
            .opt_term(
                "lease-time",
                self.lease_time.map(|d| Term::Constant {
                    value: iw_sl::Constant::DateTime(d),
                }),
            )
            .build()
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        let f = Frame::read(term, "df-agent-description")?;
        let lease_time = match f.get("lease-time") {
            None => None,
            Some(t) => match t.as_constant() {
                Some(iw_sl::Constant::DateTime(d)) => Some(*d),
                _ => {
                    return Err(OntologyError::BadValue {
                        concept: "df-agent-description",
                        slot: "lease-time",
                        value: shown(t),
                        reason: "expected a date-time",
                    });
                }
            },
        };
        Ok(Self {
            name: f.get("name").map(AgentId::from_term).transpose()?,
            services: f.concepts("services")?,
            protocols: f.texts("protocols")?,
            ontologies: f.texts("ontologies")?,
            languages: f.texts("languages")?,
            lease_time,
        })
    }
}

word_enum! {
    /// An agent's life-cycle state as the AMS reports it.
    pub enum AgentState {
        /// `initiated`
        Initiated => "initiated",
        /// `active`
        Active => "active",
        /// `suspended`
        Suspended => "suspended",
        /// `waiting`
        Waiting => "waiting",
        /// `transit`
        Transit => "transit",
    }
}

/// `(ams-agent-description ...)`: an agent's entry in the white pages.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AmsAgentDescription {
    /// `:name`
    pub name: Option<AgentId>,
    /// `:ownership`
    pub ownership: Option<String>,
    /// `:state`
    pub state: Option<AgentState>,
}

impl Concept for AmsAgentDescription {
    fn to_term(&self) -> Term {
        FrameBuilder::new("ams-agent-description")
            .opt_term("name", self.name.as_ref().map(Concept::to_term))
            .text("ownership", self.ownership.as_deref())
            .text("state", self.state.map(AgentState::name))
            .build()
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        let f = Frame::read(term, "ams-agent-description")?;
        let state = f
            .get("state")
            .map(|t| {
                word_value(
                    t,
                    "ams-agent-description",
                    "state",
                    AgentState::from_word,
                    "expected initiated, active, suspended, waiting or transit",
                )
            })
            .transpose()?;
        Ok(Self {
            name: f.get("name").map(AgentId::from_term).transpose()?,
            ownership: f.text("ownership")?,
            state,
        })
    }
}

/// A description handed to the DF or to the AMS.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", content = "value", rename_all = "kebab-case")]
pub enum AgentDescription {
    /// For the DF.
    Df(DfAgentDescription),
    /// For the AMS.
    Ams(AmsAgentDescription),
}

impl Concept for AgentDescription {
    fn to_term(&self) -> Term {
        match self {
            AgentDescription::Df(d) => d.to_term(),
            AgentDescription::Ams(d) => d.to_term(),
        }
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        if is_frame(term, "ams-agent-description") {
            AmsAgentDescription::from_term(term).map(Self::Ams)
        } else if is_frame(term, "df-agent-description") {
            DfAgentDescription::from_term(term).map(Self::Df)
        } else {
            Err(OntologyError::UnexpectedTerm {
                expected: "df-agent-description or ams-agent-description",
                found: shown(term),
            })
        }
    }
}

/// `(search-constraints ...)`: how far and how much a search may return.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SearchConstraints {
    /// `:max-depth`: how many federated DFs deep to search.
    pub max_depth: Option<i64>,
    /// `:max-results`: at most this many results; JADE uses -1 for "all".
    pub max_results: Option<i64>,
    /// `:search-id`: identifies a federated search.
    pub search_id: Option<String>,
}

impl Concept for SearchConstraints {
    fn to_term(&self) -> Term {
        FrameBuilder::new("search-constraints")
            .opt_term("max-depth", self.max_depth.map(Term::integer))
            .opt_term("max-results", self.max_results.map(Term::integer))
            .text("search-id", self.search_id.as_deref())
            .build()
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        let f = Frame::read(term, "search-constraints")?;
        Ok(Self {
            max_depth: f.integer("max-depth")?,
            max_results: f.integer("max-results")?,
            search_id: f.text("search-id")?,
        })
    }
}

/// The management actions of the AMS and DF.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ManagementAction {
    /// `(register desc)`
    Register {
        /// What to register.
        description: AgentDescription,
    },
    /// `(deregister desc)`
    Deregister {
        /// What to remove (its `:name` matters).
        description: AgentDescription,
    },
    /// `(modify desc)`
    Modify {
        /// The new description.
        description: AgentDescription,
    },
    /// `(search template constraints)`
    Search {
        /// Template: entries matching every slot set.
        description: AgentDescription,
        /// Limits.
        constraints: SearchConstraints,
    },
    /// `(get-description)`: the platform's description.
    GetDescription,
}

impl Concept for ManagementAction {
    fn to_term(&self) -> Term {
        let (symbol, args) = match self {
            Self::Register { description } => ("register", vec![description.to_term()]),
            Self::Deregister { description } => ("deregister", vec![description.to_term()]),
            Self::Modify { description } => ("modify", vec![description.to_term()]),
            Self::Search {
                description,
                constraints,
            } => ("search", vec![description.to_term(), constraints.to_term()]),
            Self::GetDescription => ("get-description", vec![]),
        };
        Term::positional(symbol, args)
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        const EXPECTED: &str = "register, deregister, modify, search or get-description";
        let Term::Functional {
            symbol,
            args: Arguments::Positional(_),
        } = term
        else {
            return Err(OntologyError::UnexpectedTerm {
                expected: EXPECTED,
                found: shown(term),
            });
        };
        let symbol = symbol.to_ascii_lowercase();
        let action = match symbol.as_str() {
            "register" => Self::Register {
                description: description_arg(term, "register")?,
            },
            "deregister" => Self::Deregister {
                description: description_arg(term, "deregister")?,
            },
            "modify" => Self::Modify {
                description: description_arg(term, "modify")?,
            },
            "search" => {
                let f = Frame::read(term, "search")?;
                let constraints = match f.positional().get(1) {
                    Some(c) => SearchConstraints::from_term(c)?,
                    None => SearchConstraints::default(),
                };
                Self::Search {
                    description: AgentDescription::from_term(f.arg(0, "description")?)?,
                    constraints,
                }
            }
            "get-description" => Self::GetDescription,
            _ => {
                return Err(OntologyError::UnexpectedTerm {
                    expected: EXPECTED,
                    found: shown(term),
                });
            }
        };
        Ok(action)
    }
}

fn description_arg(term: &Term, action: &'static str) -> Result<AgentDescription, OntologyError> {
    AgentDescription::from_term(Frame::read(term, action)?.arg(0, "description")?)
}

/// `(action actor act)`: `actor` (the AMS or DF) is asked to perform `action`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ManagementRequest {
    /// The AMS or DF.
    pub actor: AgentId,
    /// What it should do.
    pub action: ManagementAction,
}

impl ManagementRequest {
    /// As an SL action expression.
    pub fn to_action(&self) -> ActionExpression {
        ActionExpression::Action {
            agent: self.actor.to_term(),
            act: self.action.to_term(),
        }
    }

    /// From an SL action expression.
    pub fn from_action(action: &ActionExpression) -> Result<Self, OntologyError> {
        match action {
            ActionExpression::Action { agent, act } => Ok(Self {
                actor: AgentId::from_term(agent)?,
                action: ManagementAction::from_term(act)?,
            }),
            other => Err(OntologyError::UnexpectedTerm {
                expected: "(action actor act)",
                found: other.to_string(),
            }),
        }
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        match term {
            Term::Action { action } => Self::from_action(action),
            _ => Err(OntologyError::UnexpectedTerm {
                expected: "(action actor act)",
                found: shown(term),
            }),
        }
    }
}

/// The FIPA exceptions (SC00023 §6.3) carried by NOT-UNDERSTOOD, REFUSE and FAILURE, plus the
/// `MTS-error` JADE's AMS sends when a message cannot be delivered.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
#[non_exhaustive]
pub enum FipaError {
    /// `unauthorised` (refuse).
    Unauthorised,
    /// `already-registered` (failure).
    AlreadyRegistered,
    /// `not-registered` (failure).
    NotRegistered,
    /// `(unsupported-function f)` (refuse).
    UnsupportedFunction {
        /// The function.
        function: String,
    },
    /// `(internal-error "msg")` (failure).
    InternalError {
        /// What went wrong.
        message: String,
    },
    /// `(unsupported-act act)` (not-understood).
    UnsupportedAct {
        /// The performative.
        act: String,
    },
    /// `(unexpected-act act)` (not-understood).
    UnexpectedAct {
        /// The performative.
        act: String,
    },
    /// `(unsupported-value v)` (not-understood).
    UnsupportedValue {
        /// The message parameter.
        value: String,
    },
    /// `(unrecognised-value v)` (not-understood).
    UnrecognisedValue {
        /// The message parameter.
        value: String,
    },
    /// `(missing-argument a)` (refuse).
    MissingArgument {
        /// The argument.
        argument: String,
    },
    /// `(unexpected-argument a)` (refuse).
    UnexpectedArgument {
        /// The argument.
        argument: String,
    },
    /// `unexpected-argument-count` (refuse).
    UnexpectedArgumentCount,
    /// `(missing-parameter object parameter)` (refuse).
    MissingParameter {
        /// The concept.
        object: String,
        /// Its missing slot.
        parameter: String,
    },
    /// `(unexpected-parameter object parameter)` (refuse).
    UnexpectedParameter {
        /// The concept.
        object: String,
        /// The unexpected slot.
        parameter: String,
    },
    /// `(unrecognised-parameter-value parameter value)` (refuse).
    UnrecognisedParameterValue {
        /// The slot.
        parameter: String,
        /// Its value.
        value: String,
    },
    /// `(MTS-error receiver reason)`: delivery to `receiver` failed (JADE's AMS).
    MtsError {
        /// Who could not be reached.
        receiver: AgentId,
        /// Why.
        reason: Box<FipaError>,
    },
}

impl FipaError {
    /// The predicate symbol and its arguments.
    fn parts(&self) -> (&'static str, Vec<Term>) {
        let s = |x: &String| Term::string(x.as_str());
        match self {
            Self::Unauthorised => ("unauthorised", vec![]),
            Self::AlreadyRegistered => ("already-registered", vec![]),
            Self::NotRegistered => ("not-registered", vec![]),
            Self::UnexpectedArgumentCount => ("unexpected-argument-count", vec![]),
            Self::UnsupportedFunction { function } => ("unsupported-function", vec![s(function)]),
            Self::InternalError { message } => ("internal-error", vec![s(message)]),
            Self::UnsupportedAct { act } => ("unsupported-act", vec![s(act)]),
            Self::UnexpectedAct { act } => ("unexpected-act", vec![s(act)]),
            Self::UnsupportedValue { value } => ("unsupported-value", vec![s(value)]),
            Self::UnrecognisedValue { value } => ("unrecognised-value", vec![s(value)]),
            Self::MissingArgument { argument } => ("missing-argument", vec![s(argument)]),
            Self::UnexpectedArgument { argument } => ("unexpected-argument", vec![s(argument)]),
            Self::MissingParameter { object, parameter } => {
                ("missing-parameter", vec![s(object), s(parameter)])
            }
            Self::UnexpectedParameter { object, parameter } => {
                ("unexpected-parameter", vec![s(object), s(parameter)])
            }
            Self::UnrecognisedParameterValue { parameter, value } => {
                ("unrecognised-parameter-value", vec![s(parameter), s(value)])
            }
            Self::MtsError { receiver, reason } => {
                ("MTS-error", vec![receiver.to_term(), reason.to_term()])
            }
        }
    }

    fn from_parts(
        symbol: &str,
        args: &[Term],
        shown_as: impl Fn() -> String,
    ) -> Result<Self, OntologyError> {
        let bad = || OntologyError::UnexpectedTerm {
            expected: "a FIPA exception",
            found: shown_as(),
        };
        let text = |i: usize| args.get(i).and_then(text_of).ok_or_else(bad);
        let symbol = symbol.to_ascii_lowercase();
        let arity = |n: usize| if args.len() == n { Ok(()) } else { Err(bad()) };
        Ok(match symbol.as_str() {
            "unauthorised" => arity(0).map(|()| Self::Unauthorised)?,
            "already-registered" => arity(0).map(|()| Self::AlreadyRegistered)?,
            "not-registered" => arity(0).map(|()| Self::NotRegistered)?,
            "unexpected-argument-count" => arity(0).map(|()| Self::UnexpectedArgumentCount)?,
            "unsupported-function" => Self::UnsupportedFunction { function: text(0)? },
            "internal-error" => Self::InternalError { message: text(0)? },
            "unsupported-act" => Self::UnsupportedAct { act: text(0)? },
            "unexpected-act" => Self::UnexpectedAct { act: text(0)? },
            "unsupported-value" => Self::UnsupportedValue { value: text(0)? },
            "unrecognised-value" => Self::UnrecognisedValue { value: text(0)? },
            "missing-argument" => Self::MissingArgument { argument: text(0)? },
            "unexpected-argument" => Self::UnexpectedArgument { argument: text(0)? },
            "missing-parameter" => Self::MissingParameter {
                object: text(0)?,
                parameter: text(1)?,
            },
            "unexpected-parameter" => Self::UnexpectedParameter {
                object: text(0)?,
                parameter: text(1)?,
            },
            "unrecognised-parameter-value" => Self::UnrecognisedParameterValue {
                parameter: text(0)?,
                value: text(1)?,
            },
            "mts-error" => {
                let (Some(receiver), Some(reason)) = (args.first(), args.get(1)) else {
                    return Err(bad());
                };
                Self::MtsError {
                    receiver: AgentId::from_term(receiver)?,
                    reason: Box::new(Self::from_term(reason)?),
                }
            }
            _ => return Err(bad()),
        })
    }

    /// As a content formula: `already-registered` or `(internal-error "msg")`.
    pub fn to_formula(&self) -> Formula {
        let (symbol, args) = self.parts();
        if args.is_empty() {
            Formula::Symbol {
                name: symbol.into(),
            }
        } else {
            Formula::Atomic {
                predicate: symbol.into(),
                args,
            }
        }
    }

    /// From a content formula.
    pub fn from_formula(formula: &Formula) -> Result<Self, OntologyError> {
        match formula {
            Formula::Symbol { name } => Self::from_parts(name, &[], || formula.to_string()),
            Formula::Atomic { predicate, args } => {
                Self::from_parts(predicate, args, || formula.to_string())
            }
            _ => Err(OntologyError::UnexpectedTerm {
                expected: "a FIPA exception",
                found: formula.to_string(),
            }),
        }
    }
}

impl Concept for FipaError {
    /// As a term (inside `MTS-error`): `(internal-error "msg")`, or the bare word.
    fn to_term(&self) -> Term {
        let (symbol, args) = self.parts();
        if args.is_empty() {
            Term::string(symbol)
        } else {
            Term::positional(symbol, args)
        }
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        match term {
            Term::Functional {
                symbol,
                args: Arguments::Positional(args),
            } => Self::from_parts(symbol, args, || shown(term)),
            Term::Constant {
                value: iw_sl::Constant::String(s),
            } => Self::from_parts(s, &[], || shown(term)),
            _ => Err(OntologyError::UnexpectedTerm {
                expected: "a FIPA exception",
                found: shown(term),
            }),
        }
    }
}

/// The content forms of FIPA-Agent-Management conversations.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ManagementContent {
    /// REQUEST: `((action actor act))`.
    Request(ManagementRequest),
    /// INFORM after success: `((done (action ...)))`.
    Done(ManagementRequest),
    /// INFORM with results: `((result (action ...) (sequence desc...)))`.
    Result {
        /// The action answered.
        request: ManagementRequest,
        /// The descriptions found.
        descriptions: Vec<AgentDescription>,
    },
    /// SUBSCRIBE to search results: `((iota ?x (result (action ...) ?x)))` (full SL).
    Subscribe(ManagementRequest),
    /// INFORM notifying a subscriber: `((= (iota ?x (result ...)) (sequence desc...)))` (full SL).
    Notification {
        /// The subscribed search.
        request: ManagementRequest,
        /// The descriptions that changed.
        descriptions: Vec<AgentDescription>,
    },
    /// REFUSE, FAILURE: `((action ...) reason)`. The action is kept as SL: JADE's AMS names
    /// actions outside this ontology here (`(ACLMessage)` for a failed delivery).
    Failure {
        /// The action refused or failed.
        action: ActionExpression,
        /// Why.
        reason: FipaError,
    },
}

const FORMS: &str = "(action ..), (done ..), (result ..), (iota ?x (result ..)), (= (iota ..) ..) or (action ..) reason";

impl ManagementContent {
    /// The lowest SL level that can carry this content (`fipa-sl0` except for subscriptions).
    pub fn level(&self) -> Level {
        match self {
            Self::Subscribe(_) | Self::Notification { .. } => Level::Full,
            _ => Level::Sl0,
        }
    }

    /// As SL content.
    pub fn to_content(&self) -> Content {
        let result_of = |request: &ManagementRequest, value: Term| Formula::Atomic {
            predicate: "result".into(),
            args: vec![
                Term::Action {
                    action: Box::new(request.to_action()),
                },
                value,
            ],
        };
        let subscription = |request: &ManagementRequest| IdentifyingExpression {
            op: ReferentialOp::Iota,
            term: Term::variable("x"),
            formula: result_of(request, Term::variable("x")),
        };
        let descriptions =
            |d: &[AgentDescription]| Term::sequence(d.iter().map(Concept::to_term).collect());
        match self {
            Self::Request(r) => Content::single(r.to_action()),
            Self::Done(r) => Content::single(Formula::ActionCondition {
                op: iw_sl::ActionOp::Done,
                action: Box::new(iw_sl::ActionOperand::Expression(r.to_action())),
                condition: None,
            }),
            Self::Result {
                request,
                descriptions: d,
            } => Content::single(result_of(request, descriptions(d))),
            Self::Subscribe(r) => Content::single(subscription(r)),
            Self::Notification {
                request,
                descriptions: d,
            } => Content::single(Formula::Atomic {
                predicate: "=".into(),
                args: vec![
                    Term::Identifying {
                        expression: Box::new(subscription(request)),
                    },
                    descriptions(d),
                ],
            }),
            Self::Failure { action, reason } => Content {
                expressions: vec![
                    ContentExpression::Action(action.clone()),
                    reason.to_formula().into(),
                ],
            },
        }
    }

    /// Parses `text` at `level` and reads it.
    pub fn parse(text: &str, level: Level) -> Result<Self, OntologyError> {
        Self::from_content(&iw_sl::parse(text, level)?)
    }

    /// Reads SL content.
    pub fn from_content(content: &Content) -> Result<Self, OntologyError> {
        let unexpected = || OntologyError::UnexpectedContent {
            expected: FORMS,
            found: content.to_string(),
        };
        match content.expressions.as_slice() {
            [ContentExpression::Action(a)] => ManagementRequest::from_action(a).map(Self::Request),
            [
                ContentExpression::Action(action),
                ContentExpression::Formula(reason),
            ] => Ok(Self::Failure {
                action: action.clone(),
                reason: FipaError::from_formula(reason)?,
            }),
            [
                ContentExpression::Formula(Formula::ActionCondition {
                    op: iw_sl::ActionOp::Done,
                    action,
                    ..
                }),
            ] => match action.as_ref() {
                iw_sl::ActionOperand::Expression(a) => {
                    ManagementRequest::from_action(a).map(Self::Done)
                }
                iw_sl::ActionOperand::Meta(_) => Err(unexpected()),
            },
            [ContentExpression::Formula(Formula::Atomic { predicate, args })] => match args
                .as_slice()
            {
                [action, value] if predicate.eq_ignore_ascii_case("result") => Ok(Self::Result {
                    request: ManagementRequest::from_term(action)?,
                    descriptions: descriptions_of(value)?,
                }),
                [Term::Identifying { expression }, value] if predicate == "=" => {
                    Ok(Self::Notification {
                        request: subscribed_request(expression)?,
                        descriptions: descriptions_of(value)?,
                    })
                }
                _ => Err(unexpected()),
            },
            [ContentExpression::Identifying(i)] => subscribed_request(i).map(Self::Subscribe),
            _ => Err(unexpected()),
        }
    }
}

fn descriptions_of(value: &Term) -> Result<Vec<AgentDescription>, OntologyError> {
    match value.collection() {
        Some((_, items)) => items.iter().map(AgentDescription::from_term).collect(),
        None => Err(OntologyError::UnexpectedTerm {
            expected: "a set or sequence of descriptions",
            found: shown(value),
        }),
    }
}

/// The request inside `(iota ?x (result (action ...) ?x))`.
fn subscribed_request(i: &IdentifyingExpression) -> Result<ManagementRequest, OntologyError> {
    let bad = || OntologyError::UnexpectedTerm {
        expected: "(iota ?x (result (action ...) ?x))",
        found: i.to_string(),
    };
    match (&i.op, &i.term, &i.formula) {
        (ReferentialOp::Iota, Term::Variable { name }, Formula::Atomic { predicate, args })
            if predicate.eq_ignore_ascii_case("result") =>
        {
            match args.as_slice() {
                [action, Term::Variable { name: v }] if v == name => {
                    ManagementRequest::from_term(action)
                }
                _ => Err(bad()),
            }
        }
        _ => Err(bad()),
    }
}
