//! `taxel bridge`: the pads of one or more devices published into Zenoh in the form ROS 2's
//! rmw_zenoh uses, so ROS 2 nodes (and plain Zenoh subscribers) receive them. The design, the
//! message types and the names are in docs/BRIDGE.md.
//!
//! The devices are read by the host library (`taxel_host`): each by a `DeviceSession` on a
//! thread of the `Worker`, into one queue; their frames are stamped by its one policy
//! (`taxel_host::stamping`).
//!
//! - [`relay`]: the worker's events to stamped messages, each device's health, the publishing
//!   loop;
//! - [`health`]: a device's state as a ROS 2 diagnostic status (a pad's frames become messages
//!   in `taxel_ros2::pad_messages`);
//! - [`names`]: rmw_zenoh's key expressions, liveliness tokens, GIDs and attachment;
//! - [`sequence`]: the device's 32-bit sequence numbers as a publisher's 64-bit ones from 1;
//! - [`publisher`]: the Zenoh session and the publishers in the ROS 2 form;
//! - [`commands`]: the devices' tare and use case, and each pad's tare, served to ROS 2
//!   (`--allow-commands`);
//! - [`plain`]: the plain mode, for Zenoh users without ROS;
//! - [`network`]: the Zenoh session's endpoints and their defaults;
//! - [`reconnect`]: a device that went away looked for again on its port until it is back;
//! - [`foxglove`]: a live view in Foxglove (`--foxglove`): a Foxglove WebSocket server, its
//!   messages built by [`foxglove_messages`]; [`fanout`] gives every message to it and to the
//!   Zenoh side;
//! - [`run`]: a run of the bridge from its [`run::BridgeConfig`] (the command line that fills
//!   one is the `taxel-bridge` program's, in the `taxel-bridge-cli` package).
#![deny(missing_docs)]
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod commands;
pub mod fanout;
pub mod foxglove;
pub mod foxglove_messages;
pub mod health;
pub mod names;
pub mod network;
pub mod plain;
pub mod publisher;
pub mod reconnect;
pub mod relay;
pub mod run;
pub mod sequence;
