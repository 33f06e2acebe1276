//! `taxel bridge`: the pads of one or more devices published into Zenoh in the form ROS 2's
//! rmw_zenoh uses, so ROS 2 nodes (and plain Zenoh subscribers) receive them. The design, the
//! message types and the names are in docs/BRIDGE.md.
//!
//! - [`device_reader`]: one thread per device, stamping frames with the mapped device time and
//!   queueing them without ever blocking;
//! - [`health`]: a device's state as a ROS 2 diagnostic status (a pad's frames become messages
//!   in `taxel_ros2::pad_messages`);
//! - [`names`]: rmw_zenoh's key expressions, liveliness tokens and attachment;
//! - [`publisher`]: the Zenoh session and the publishing loop in the ROS 2 form;
//! - [`plain`]: the plain mode, for Zenoh users without ROS;
//! - [`command`]: the command line and the run.
#![deny(missing_docs)]
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod command;
pub mod device_reader;
pub mod health;
pub mod names;
pub mod plain;
pub mod publisher;
