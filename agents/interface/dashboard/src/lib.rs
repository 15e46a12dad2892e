//! The dashboard, served on the interface agent's side: an on-chair display and a staff view in a
//! browser, fed compact JSON state over a websocket; what the page asks for comes back as
//! [`PageAction`]s for the interface side to send on the bus like any agent.
//!
//! Organization:
//! - [`Dashboard`]: the HTTP + websocket server (its own thread and tokio runtime);
//!   [`Dashboard::publish`] hands it the state, [`Dashboard::try_action`] takes the page's asks.
//! - [`DashboardConfig`]: where it binds and its access token; [`ConnectionLimits`]: what a
//!   client may hold before it is authenticated (connection cap, header and HTTP timeouts, a
//!   per-source connection rate).
//! - [`MapView`], [`State`], [`ChairView`], [`ChairDisplay`], [`MessageView`], [`ContainerView`],
//!   [`FeatureView`]: what the page is sent (the map once, the state at each publish).
//! - [`PageAction`]: what the page may ask; [`DriveInput`]: the drive panel's inputs (on-screen
//!   joystick, gamepad, arrow keys, head-cap emulation), for the chair's interface agent.
//!
//! Routes: `/` (staff view; `/?chair=NAME` is that chair's on-board display), `/map.json`, `/ws`.
//! It binds 127.0.0.1 by default; any other address needs a token, which every request must then
//! carry as `?token=` or an `Authorization: Bearer` header (401 otherwise).

mod server;
mod state;

pub use server::{
    ACTIONS_BURST, ACTIONS_PER_S, ConnectionLimits, Dashboard, DashboardConfig, DashboardError,
};
pub use state::{
    ChairDisplay, ChairView, ContainerView, DoorView, DriveInput, FeatureView, MapView,
    MessageView, PageAction, PassageView, PlaceView, State, round_cm,
};
