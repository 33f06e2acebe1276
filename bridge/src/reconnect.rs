//! A device that goes away comes back by itself: while its state is
//! [`ReaderState::Reconnecting`](crate::health::ReaderState::Reconnecting), its port is opened
//! again every [`RETRY_PERIOD`] on a thread of its own (the relay never waits for a port), and
//! once the board answers and its stream starts, the worker reads it again under its number
//! ([`taxel_host::worker::Worker::reattach`]) and the relay estimates its clock anew
//! ([`crate::relay::Relay::reattached`]). A board whose pads differ from the ones published is
//! refused. Only devices given by port are looked for again (a simulated device's port goes
//! with it).

use std::sync::mpsc::{self, Receiver, TryRecvError};
use std::time::{Duration, Instant};

use taxel_host::console::error_message;
use taxel_host::noteln;
use taxel_host::worker::Worker;
use wire::PadInfoFrame;

use crate::relay::Relay;
use crate::run::{open_device, PortSession};

/// How often a device that went away is looked for.
pub const RETRY_PERIOD: Duration = Duration::from_millis(500);

/// A port opened, its device identified, described and streaming.
type Opened = anyhow::Result<(PortSession, Vec<PadInfoFrame>)>;

/// Where a device's search stands.
enum Search {
    /// The next attempt is due then.
    Waiting(Instant),
    /// An attempt runs on its thread.
    Opening(Receiver<Opened>),
}

/// Every device's search for its board (see the module documentation).
pub struct Reconnector {
    ports: Vec<String>,
    request_timeout: Duration,
    searches: Vec<Option<Search>>,
}

impl Reconnector {
    /// Searches for the boards of `ports` (the bridge's device `n` is on `ports[n]`).
    pub fn new(ports: Vec<String>, request_timeout: Duration) -> Self {
        let searches = ports.iter().map(|_| None).collect();
        Self {
            ports,
            request_timeout,
            searches,
        }
    }

    /// Starts the attempts that are due and takes the boards that came back (between two
    /// events of the relay loop; never waits).
    pub fn poll(
        &mut self,
        worker: &mut Worker<Box<dyn serialport::SerialPort>>,
        relay: &mut Relay,
    ) {
        let now = Instant::now();
        let looking = relay.reconnecting();
        for (device, search) in self.searches.iter_mut().enumerate() {
            let Some(&(_, worker_device)) = looking.iter().find(|(known, _)| *known == device)
            else {
                *search = None;
                continue;
            };
            match search.take() {
                None => *search = Some(Search::Waiting(now + RETRY_PERIOD)),
                Some(Search::Waiting(due)) if now < due => *search = Some(Search::Waiting(due)),
                Some(Search::Waiting(_)) => {
                    let port = self.ports.get(device).cloned().unwrap_or_default();
                    *search = Some(Search::Opening(open_in_background(
                        port,
                        self.request_timeout,
                    )));
                }
                Some(Search::Opening(receiver)) => match receiver.try_recv() {
                    Err(TryRecvError::Empty) => *search = Some(Search::Opening(receiver)),
                    Err(TryRecvError::Disconnected) | Ok(Err(_)) => {
                        *search = Some(Search::Waiting(now + RETRY_PERIOD));
                    }
                    Ok(Ok((session, pads))) => {
                        let info = *session.info();
                        let name = self.ports.get(device).map_or("", String::as_str);
                        match worker.reattach(worker_device, session) {
                            Ok(()) => match relay.reattached(device, info, pads) {
                                Ok(()) => {
                                    noteln!("device {device} ({name}): back, streaming again")
                                }
                                Err(reason) => noteln!("device {device} ({name}): {reason}"),
                            },
                            Err(error) => {
                                noteln!("device {device} ({name}): {}", error_message(&error));
                                *search = Some(Search::Waiting(now + RETRY_PERIOD));
                            }
                        }
                    }
                },
            }
        }
    }
}

/// Opens `port` and starts its stream on a thread of its own; the result arrives on the
/// receiver (an error when the thread could not start).
fn open_in_background(port: String, request_timeout: Duration) -> Receiver<Opened> {
    let (sender, receiver) = mpsc::channel();
    let thread_sender = sender.clone();
    let spawned = std::thread::Builder::new()
        .name("taxel-bridge-reconnect".to_owned())
        .spawn(move || {
            let opened = open_device(&port, request_timeout).and_then(|(mut session, pads)| {
                session.start()?;
                Ok((session, pads))
            });
            // The bridge may have ended meanwhile; the device is then nobody's.
            let _ = thread_sender.send(opened);
        });
    if let Err(error) = spawned {
        let _ = sender.send(Err(anyhow::Error::new(error)));
    }
    receiver
}
