//! What the page is sent and what it may ask. Field names are short and numbers rounded to the
//! centimetre (or milliradian) so a 100-chair frame stays small at 10 Hz.

use serde::{Deserialize, Serialize};

/// Rounds `x` to 0.01 (cm for metres, 0.01 rad for angles), as `f32` so it prints short.
/// Non-finite values become 0.
pub fn round_cm(x: f64) -> f32 {
    if x.is_finite() {
        ((x * 100.0).round() / 100.0) as f32
    } else {
        0.0
    }
}

/// The static building, sent once at `/map.json`.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct MapView {
    /// Building name.
    pub name: String,
    /// Wall polylines (and furniture outlines), m.
    pub walls: Vec<Vec<[f32; 2]>>,
    /// Doors.
    pub doors: Vec<DoorView>,
    /// Named places a goal can be set to.
    pub places: Vec<PlaceView>,
    /// Narrow passages the watcher keeps one-way at a time.
    #[serde(default)]
    pub passages: Vec<PassageView>,
    /// Sonar mounts in the chair's body frame: x, y (m), heading (rad); ray `i` of a chair's
    /// `s` starts at mount `i`.
    pub sonars: Vec<[f32; 3]>,
}

/// A door of the map: its id and hinge (`a`) and free (`b`) ends, m.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct DoorView {
    pub id: String,
    pub a: [f32; 2],
    pub b: [f32; 2],
}

/// A narrow passage: its name and the strip `w` wide around the axis from `a` to `b`, m.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct PassageView {
    pub name: String,
    pub a: [f32; 2],
    pub b: [f32; 2],
    pub w: f32,
}

/// A named place, m.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct PlaceView {
    pub name: String,
    pub at: [f32; 2],
}

/// One frame of the dashboard.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct State {
    /// Simulated time, s.
    pub t: f32,
    /// Whether the simulation is paused.
    pub paused: bool,
    /// The chairs.
    pub chairs: Vec<ChairView>,
    /// Door id and whether it is open.
    pub doors: Vec<(String, bool)>,
    /// The agents of each container (AMS view).
    pub containers: Vec<ContainerView>,
    /// The last messages between containers, oldest first.
    pub msgs: Vec<MessageView>,
    /// Door refusals and answers to the page's actions, oldest first (`door: reason`).
    pub notices: Vec<String>,
    /// Messages sent so far.
    pub sent: u64,
    /// The current visual-odometry frame's features, when the perception agent publishes them.
    pub features: Option<FeatureView>,
    /// Frames the serving container's platform refused so far, per reason (`bad_tag`,
    /// `unknown_session`, ...; control-channel ones prefixed `control:`): an attack shows here.
    #[serde(default)]
    pub sec: std::collections::BTreeMap<String, u64>,
}

/// One chair in a frame.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct ChairView {
    /// Name (its container).
    pub n: String,
    /// Body kind: `virtual`, `real`, `mixed`.
    pub k: String,
    /// Pose x, y (m), heading (rad).
    pub p: [f32; 3],
    /// Linear (m/s) and angular (rad/s) speed.
    pub v: [f32; 2],
    /// Sonar ranges, m, in mount order; -1 for no echo.
    pub s: Vec<f32>,
    /// Goal, m.
    pub g: Option<[f32; 2]>,
    /// Planned path, m.
    pub path: Vec<[f32; 2]>,
    /// Pose uncertainty (1-sigma position), m.
    pub u: f32,
    /// Collisions so far.
    pub c: u64,
    /// What the chair's own screen shows.
    pub d: ChairDisplay,
}

/// The on-chair display of one chair.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct ChairDisplay {
    /// The current action (last command sent, or `idle`).
    pub action: String,
    /// The goal's place name, if any.
    pub goal: Option<String>,
    /// Shared control is intervening (an obstacle is close).
    pub warn: bool,
    /// Input sequence being recognised: steps entered, steps in the sequence.
    pub seq: Option<(usize, usize)>,
    /// The last answer the chair got.
    pub answer: Option<String>,
    /// The user's hand command being streamed: linear (m/s), angular (rad/s).
    #[serde(default)]
    pub user: Option<[f32; 2]>,
    /// What shared control made of it at the last control tick: linear (m/s), angular (rad/s).
    #[serde(default)]
    pub applied: Option<[f32; 2]>,
}

/// A container and its agents.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct ContainerView {
    pub name: String,
    pub agents: Vec<String>,
}

/// One message between containers, sniffer-style.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct MessageView {
    /// Sender agent.
    pub from: String,
    /// Receiver agent.
    pub to: String,
    /// Performative.
    pub act: String,
    /// Conversation id, if any.
    pub conv: String,
    /// Dropped by a link fault.
    pub dropped: bool,
}

/// Features of the current VO frame, in image pixels.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct FeatureView {
    /// Image width and height, px.
    pub size: [u32; 2],
    /// Hard features (drawn red).
    pub hard: Vec<[f32; 2]>,
    /// Soft features (drawn green).
    pub soft: Vec<[f32; 2]>,
}

/// What the page may ask; sent as JSON `{"do":"goal",...}` over the websocket.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(tag = "do", rename_all = "kebab-case")]
pub enum PageAction {
    /// Send `chair` towards the place nearest to (`x`, `y`), m.
    Goal { chair: String, x: f64, y: f64 },
    /// Ask the door agent to open (or close) `door`.
    Door { door: String, open: bool },
    /// Pause or resume the simulation.
    Pause { paused: bool },
    /// Advance a paused simulation by one step.
    Step,
    /// Fail (or restore) every sensor of `chair`.
    Fault { chair: String, failed: bool },
    /// A drive input for `chair`'s interface agent, sent while held (and once, centred, on
    /// release).
    Drive {
        chair: String,
        #[serde(flatten)]
        input: DriveInput,
    },
}

/// A proportional input of the drive panel (`"dev"` names the device).
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
#[serde(tag = "dev", rename_all = "kebab-case")]
pub enum DriveInput {
    /// The on-screen joystick: `x` right, `y` forward, each in [-1, 1].
    Stick { x: f64, y: f64 },
    /// The browser Gamepad API's left stick, forward positive.
    Gamepad { x: f64, y: f64 },
    /// Arrow keys held.
    Keys {
        up: bool,
        down: bool,
        left: bool,
        right: bool,
    },
    /// Head-cap emulation (sliders or the phone's orientation): forward and rightward tilt, rad.
    Head { pitch: f64, roll: f64 },
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn actions_parse_from_the_page_shape() {
        let goal: PageAction =
            serde_json::from_str(r#"{"do":"goal","chair":"chair-0","x":3.5,"y":2}"#).unwrap();
        assert_eq!(
            goal,
            PageAction::Goal {
                chair: "chair-0".into(),
                x: 3.5,
                y: 2.0
            }
        );
        let drive: PageAction =
            serde_json::from_str(r#"{"do":"drive","chair":"chair-0","dev":"stick","x":0.5,"y":1}"#)
                .unwrap();
        assert_eq!(
            drive,
            PageAction::Drive {
                chair: "chair-0".into(),
                input: DriveInput::Stick { x: 0.5, y: 1.0 }
            }
        );
        assert!(
            serde_json::from_str::<PageAction>(
                r#"{"do":"drive","chair":"c","dev":"stick","x":null,"y":1}"#
            )
            .is_err(),
            "NaN arrives as null and is refused"
        );
        let step: PageAction = serde_json::from_str(r#"{"do":"step"}"#).unwrap();
        assert_eq!(step, PageAction::Step);
        assert!(serde_json::from_str::<PageAction>(r#"{"do":"explode"}"#).is_err());
    }

    /// A number as a page's slider, stick or click sends it: up to a million, three decimals
    /// (serde_json reads such numbers exactly; its best-effort float parsing may put a
    /// 17-digit number one unit in the last place off).
    fn finite() -> impl Strategy<Value = f64> {
        (-1_000_000_000i64..=1_000_000_000).prop_map(|n| n as f64 / 1000.0)
    }

    fn drive_input() -> impl Strategy<Value = DriveInput> {
        prop_oneof![
            (finite(), finite()).prop_map(|(x, y)| DriveInput::Stick { x, y }),
            (finite(), finite()).prop_map(|(x, y)| DriveInput::Gamepad { x, y }),
            any::<[bool; 4]>().prop_map(|[up, down, left, right]| DriveInput::Keys {
                up,
                down,
                left,
                right
            }),
            (finite(), finite()).prop_map(|(pitch, roll)| DriveInput::Head { pitch, roll }),
        ]
    }

    fn page_action() -> impl Strategy<Value = PageAction> {
        let name = "\\PC{0,12}";
        prop_oneof![
            (name, finite(), finite()).prop_map(|(chair, x, y)| PageAction::Goal { chair, x, y }),
            (name, any::<bool>()).prop_map(|(door, open)| PageAction::Door { door, open }),
            any::<bool>().prop_map(|paused| PageAction::Pause { paused }),
            Just(PageAction::Step),
            (name, any::<bool>()).prop_map(|(chair, failed)| PageAction::Fault { chair, failed }),
            (name, drive_input()).prop_map(|(chair, input)| PageAction::Drive { chair, input }),
        ]
    }

    proptest! {
        /// Whatever a page sends is an action or an error, never a panic; an action it accepts
        /// reads back as the same kind of action from its own JSON.
        #[test]
        fn any_text_is_an_action_or_an_error(text in "\\PC{0,120}") {
            if let Ok(action) = serde_json::from_str::<PageAction>(&text) {
                let again = serde_json::to_string(&action).unwrap();
                let back = serde_json::from_str::<PageAction>(&again).unwrap();
                prop_assert_eq!(std::mem::discriminant(&back), std::mem::discriminant(&action));
            }
        }

        /// Every action the page can send survives the trip as JSON unchanged.
        #[test]
        fn every_action_round_trips(action in page_action()) {
            let text = serde_json::to_string(&action).unwrap();
            prop_assert_eq!(serde_json::from_str::<PageAction>(&text).unwrap(), action);
        }

        /// An action with one of its keys dropped is refused with an error, never taken as
        /// another action or filled in.
        #[test]
        fn a_mangled_action_is_refused_not_misread(action in page_action(), pick in any::<prop::sample::Index>()) {
            let mut value = serde_json::to_value(&action).unwrap();
            let object = value.as_object_mut().unwrap();
            let keys: Vec<String> = object.keys().filter(|k| *k != "do").cloned().collect();
            prop_assume!(!keys.is_empty());
            let key = &keys[pick.index(keys.len())];
            object.remove(key);
            prop_assert!(serde_json::from_value::<PageAction>(value).is_err(), "{} dropped", key);
        }
    }

    #[test]
    fn rounding_keeps_numbers_short() {
        assert_eq!(serde_json::to_string(&round_cm(1.23456)).unwrap(), "1.23");
        assert_eq!(round_cm(f64::NAN), 0.0);
    }
}
