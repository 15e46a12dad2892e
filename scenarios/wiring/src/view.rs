//! What the dashboard (`iw-dashboard`) is given, whoever feeds it: the building as the page draws
//! it, and a drive panel input as the interface agent's device reading. The demo (from the
//! in-process fleet) and the services container of a deployment (from the bus) both use these.

use iw_dashboard::{DoorView, DriveInput, MapView, PassageView, PlaceView, round_cm};
use iw_interface::RawInput;
use iw_sim::Map;
use nalgebra::Point2;

/// The building as the page draws it.
pub fn map_view(map: &Map) -> MapView {
    let pt = |p: &Point2<f64>| [round_cm(p.x), round_cm(p.y)];
    MapView {
        name: map.name.clone(),
        walls: map
            .walls
            .iter()
            .map(|w| w.iter().map(pt).collect())
            .collect(),
        doors: map
            .doors
            .iter()
            .map(|d| DoorView {
                id: d.id.clone(),
                a: pt(&d.a),
                b: pt(&d.b),
            })
            .collect(),
        places: map
            .places
            .iter()
            .map(|p| PlaceView {
                name: p.name.clone(),
                at: pt(&p.position),
            })
            .collect(),
        passages: map
            .passages
            .iter()
            .map(|p| PassageView {
                name: p.name.clone(),
                a: pt(&p.a),
                b: pt(&p.b),
                w: round_cm(p.width_m),
            })
            .collect(),
        sonars: iw_sim::ChairSpec::default()
            .sonars
            .iter()
            .map(|m| {
                [
                    round_cm(m.t_body_sonar.translation.x),
                    round_cm(m.t_body_sonar.translation.y),
                    round_cm(m.t_body_sonar.rotation.angle()),
                ]
            })
            .collect(),
    }
}

/// A drive panel input as the reading of the device it emulates.
pub fn raw_input(input: DriveInput) -> RawInput {
    match input {
        DriveInput::Stick { x, y } => RawInput::Joystick { x, y },
        DriveInput::Gamepad { x, y } => RawInput::GamepadStick { x, y },
        DriveInput::Keys {
            up,
            down,
            left,
            right,
        } => RawInput::Arrows {
            up,
            down,
            left,
            right,
        },
        DriveInput::Head { pitch, roll } => RawInput::HeadCap {
            pitch_rad: pitch,
            roll_rad: roll,
        },
    }
}
