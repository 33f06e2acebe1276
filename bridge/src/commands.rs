//! Commands from ROS 2, served only with `--allow-commands`: per device `d`, two services, and
//! one per pad `p` of the device, in rmw_zenoh's form (its docs/design.md, "Service servers",
//! and rmw_zenoh_cpp's `rmw_service_data.cpp`):
//!
//! - `<namespace>/device<d>/tare` (`std_srvs/srv/Trigger`): the device's Tare of every pad, over
//!   [`CommandSettings::tare_sample_sets`] sample sets;
//! - `<namespace>/device<d>/pad<p>/tare` (`std_srvs/srv/Trigger`, named like the pad's topics):
//!   the device's Tare of pad `p` only, over as many sample sets; the other pads keep their
//!   baselines and go on streaming undisturbed. Served for the pads the device reported when
//!   the bridge opened it (a device that did not answer then has no per-pad services);
//! - `<namespace>/device<d>/set_use_case` (`taxel_msgs/srv/SetUseCase`,
//!   ros2-messages/srv/SetUseCase.srv): the device's SetUseCase; the reply names the model tier
//!   the device chose.
//!
//! Calibration writes (WriteCalibration, SaveCalibration, RestoreDefaults, SetPadGeometry) are
//! never served.
//!
//! Each service is a queryable on its key expression, declared complete (rmw_zenoh's clients
//! query with target `ALL_COMPLETE`), with a service server's liveliness token (`SS`) of the
//! bridge's node. A request carries rmw_zenoh's attachment (the client's sequence number,
//! timestamp and GID) and the CDR request; the reply, on the service's key expression, carries
//! the CDR response and an attachment with the request's sequence number and client GID. A call
//! goes to the device through the host library's worker (`Worker::send`: the device's thread
//! sends it between reads and keeps reading while it waits), and is answered when the device
//! answers, refuses, goes away, or does not answer within its timeout: `success` false and a
//! message that says why in every case but the first.

use std::io::{Read, Write};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::{Duration, Instant};

use taxel_host::device_link::RequestError;
use taxel_host::device_words::tier_words;
use taxel_host::noteln;
use taxel_host::worker::Worker;
use taxel_ros2::services::{read_trigger_request, SET_USE_CASE_SERVICE, TRIGGER_SERVICE};
use taxel_ros2::{ServiceResponse, ServiceType, SetUseCaseRequest};
use wire::{Command, ErrorCode, PadIndex, ReplyPayload, UseCase};
use zenoh::handlers::FifoChannelHandler;
use zenoh::liveliness::LivelinessToken;
use zenoh::query::{Query, Queryable};
use zenoh::{Session, Wait};

use crate::names::{attachment, key_expression, Attachment, GraphNode};
use crate::publisher::Naming;
use crate::relay::Relay;

/// The sample sets a tare averages unless `--tare-sets` says otherwise (as `taxel view`'s).
pub const DEFAULT_TARE_SAMPLE_SETS: u16 = 64;

/// The time a tare's reply may take per sample set beyond the request timeout: the slowest
/// rate is 25 sets per second (eight pads on a 100 kHz bus), and a margin.
const TARE_TIME_PER_SET: Duration = Duration::from_millis(50);

/// A device command served from ROS 2.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommandKind {
    /// `std_srvs/srv/Trigger` on `<namespace>/device<d>/tare`.
    Tare,
    /// `taxel_msgs/srv/SetUseCase` on `<namespace>/device<d>/set_use_case`.
    SetUseCase,
}

impl CommandKind {
    /// Every command, in the order their services are declared.
    pub const ALL: [CommandKind; 2] = [CommandKind::Tare, CommandKind::SetUseCase];

    /// The service's last name chunk.
    pub fn word(self) -> &'static str {
        match self {
            Self::Tare => "tare",
            Self::SetUseCase => "set_use_case",
        }
    }

    /// The service of device `device` under `namespace` (`/taxel`).
    pub fn service_name(self, namespace: &str, device: usize) -> String {
        format!(
            "{}/device{device}/{}",
            namespace.trim_end_matches('/'),
            self.word()
        )
    }

    /// The service of pad `pad` of device `device` under `namespace`, beside the pad's topics
    /// (only [`CommandKind::Tare`] is served per pad).
    pub fn pad_service_name(self, namespace: &str, device: usize, pad: PadIndex) -> String {
        format!(
            "{}/device{device}/pad{}/{}",
            namespace.trim_end_matches('/'),
            pad.get(),
            self.word()
        )
    }

    /// The service's type.
    pub fn service_type(self) -> &'static ServiceType {
        match self {
            Self::Tare => &TRIGGER_SERVICE,
            Self::SetUseCase => &SET_USE_CASE_SERVICE,
        }
    }
}

/// How commands are carried out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CommandSettings {
    /// The sample sets a tare averages.
    pub tare_sample_sets: u16,
    /// How long a device has to answer a request (a tare: this and its sets).
    pub request_timeout: Duration,
}

impl CommandSettings {
    /// How long the device has to answer `kind`.
    pub fn timeout(&self, kind: CommandKind) -> Duration {
        match kind {
            CommandKind::Tare => {
                self.request_timeout + TARE_TIME_PER_SET * u32::from(self.tare_sample_sets)
            }
            CommandKind::SetUseCase => self.request_timeout,
        }
    }
}

/// One service: its queryable and token.
struct Server {
    device: usize,
    kind: CommandKind,
    // The one pad the service is for, or the whole device.
    pad: Option<PadIndex>,
    key: String,
    queryable: Queryable<FifoChannelHandler<Query>>,
    _token: LivelinessToken,
}

/// A call sent to its device and not answered yet.
struct PendingCall {
    query: Query,
    key: String,
    request: Attachment,
    device: usize,
    kind: CommandKind,
    pad: Option<PadIndex>,
    reply: Receiver<Result<ReplyPayload, RequestError>>,
    deadline: Instant,
    timeout: Duration,
}

/// Every device's services and the calls under way (see the module documentation).
pub struct DeviceCommands {
    servers: Vec<Server>,
    pending: Vec<PendingCall>,
    settings: CommandSettings,
}

fn zenoh_error(error: zenoh::Error) -> anyhow::Error {
    anyhow::anyhow!("zenoh: {error}")
}

impl DeviceCommands {
    /// Declares the services of devices `0..pad_counts.len()` on `session`, with a tare of
    /// each of device `d`'s first `pad_counts[d]` pads, as entities of `node` numbered from
    /// `next_entity_id` on.
    pub fn declare(
        session: &Session,
        node: &GraphNode,
        next_entity_id: &mut u32,
        naming: &Naming,
        pad_counts: &[u8],
        settings: CommandSettings,
    ) -> anyhow::Result<Self> {
        let mut servers = Vec::new();
        for (device, &pad_count) in pad_counts.iter().enumerate() {
            let device_services = CommandKind::ALL.into_iter().map(|kind| (kind, None));
            let pad_services = (0..pad_count)
                .filter_map(PadIndex::new)
                .map(|pad| (CommandKind::Tare, Some(pad)));
            for (kind, pad) in device_services.chain(pad_services) {
                let name = match pad {
                    Some(pad) => kind.pad_service_name(&naming.namespace, device, pad),
                    None => kind.service_name(&naming.namespace, device),
                };
                let key = key_expression(
                    naming.domain_id,
                    &name,
                    kind.service_type(),
                    naming.ros_distro,
                );
                let queryable = session
                    .declare_queryable(key.as_str())
                    .complete(true)
                    .wait()
                    .map_err(zenoh_error)?;
                let token = session
                    .liveliness()
                    .declare_token(node.service_token(*next_entity_id, &name, kind.service_type()))
                    .wait()
                    .map_err(zenoh_error)?;
                *next_entity_id += 1;
                servers.push(Server {
                    device,
                    kind,
                    pad,
                    key,
                    queryable,
                    _token: token,
                });
            }
        }
        Ok(Self {
            servers,
            pending: Vec::new(),
            settings,
        })
    }

    /// Takes the requests that arrived, sends each to its device, and answers the calls whose
    /// device answered, refused, went away, or let their time pass.
    pub fn poll<P: Read + Write + Send + 'static>(&mut self, worker: &Worker<P>, relay: &Relay) {
        let mut arrived = Vec::new();
        for (index, server) in self.servers.iter().enumerate() {
            while let Ok(Some(query)) = server.queryable.try_recv() {
                arrived.push((index, query));
            }
        }
        for (index, query) in arrived {
            if let Some(server) = self.servers.get(index) {
                let service = Service {
                    device: server.device,
                    kind: server.kind,
                    pad: server.pad,
                };
                self.start(query, service, server.key.clone(), worker, relay);
            }
        }
        let now = Instant::now();
        for call in std::mem::take(&mut self.pending) {
            let response = match call.reply.try_recv() {
                Ok(result) => outcome(call.kind, call.pad, self.settings, result),
                Err(TryRecvError::Empty) if now < call.deadline => {
                    self.pending.push(call);
                    continue;
                }
                Err(TryRecvError::Empty) => ServiceResponse::failed(format!(
                    "no answer within {} ms",
                    call.timeout.as_millis()
                )),
                Err(TryRecvError::Disconnected) => {
                    ServiceResponse::failed("the device went away before it answered")
                }
            };
            call.answer(response, relay);
        }
    }

    fn start<P: Read + Write + Send + 'static>(
        &mut self,
        query: Query,
        service: Service,
        key: String,
        worker: &Worker<P>,
        relay: &Relay,
    ) {
        let Service { device, kind, pad } = service;
        let request = query
            .attachment()
            .and_then(|bytes| Attachment::parse(&bytes.to_bytes()));
        let Some(request) = request else {
            noteln!(
                "device {device}: a {} request without rmw_zenoh's attachment, refused",
                service.words()
            );
            let _ = query
                .reply_err("a request needs rmw_zenoh's attachment: sequence number, source timestamp, client GID")
                .wait();
            return;
        };
        let payload = query
            .payload()
            .map(|payload| payload.to_bytes().into_owned())
            .unwrap_or_default();
        let timeout = self.settings.timeout(kind);
        let sent = command_of(kind, pad, &payload, self.settings).and_then(|command| {
            let worker_device = relay
                .command_target(device)
                .map_err(ServiceResponse::failed)?;
            worker
                .send(worker_device, command, timeout)
                .map_err(|_| ServiceResponse::failed("the device went away"))
        });
        match sent {
            Ok(reply) => self.pending.push(PendingCall {
                query,
                key,
                request,
                device,
                kind,
                pad,
                reply,
                deadline: Instant::now() + timeout + Duration::from_millis(200),
                timeout,
            }),
            Err(response) => answer(&query, &key, &request, service, response, relay),
        }
    }

    /// Answers every call still waiting (the bridge is stopping) and undeclares the services.
    pub fn finish(self, relay: &Relay) {
        for call in self.pending {
            call.answer(
                ServiceResponse::failed("the bridge stopped before the device answered"),
                relay,
            );
        }
    }
}

/// Which service a call came to.
#[derive(Debug, Clone, Copy)]
struct Service {
    device: usize,
    kind: CommandKind,
    pad: Option<PadIndex>,
}

impl Service {
    /// The service, for people: `tare`, `pad 1 tare`.
    fn words(self) -> String {
        match self.pad {
            Some(pad) => format!("pad {} {}", pad.get(), self.kind.word()),
            None => self.kind.word().to_owned(),
        }
    }
}

/// The device command of a request to `kind` (of pad `pad` only, if given), or the response
/// refusing it.
fn command_of(
    kind: CommandKind,
    pad: Option<PadIndex>,
    payload: &[u8],
    settings: CommandSettings,
) -> Result<Command, ServiceResponse> {
    match kind {
        CommandKind::Tare => read_trigger_request(payload)
            .map(|()| Command::Tare {
                sample_sets: settings.tare_sample_sets,
                pad,
            })
            .map_err(|error| {
                ServiceResponse::failed(format!("not a std_srvs/srv/Trigger request: {error}"))
            }),
        CommandKind::SetUseCase => SetUseCaseRequest::from_cdr(payload)
            .map(|request| {
                Command::SetUseCase(UseCase {
                    pressure_max_kpa: request.pressure_max_kpa,
                    temperature_min_c: request.temperature_min_c,
                    temperature_max_c: request.temperature_max_c,
                    error_budget_kpa: request.error_budget_kpa,
                })
            })
            .map_err(|error| {
                ServiceResponse::failed(format!("not a taxel_msgs/srv/SetUseCase request: {error}"))
            }),
    }
}

/// The response to the device's answer to `kind` (of pad `pad` only, if given).
fn outcome(
    kind: CommandKind,
    pad: Option<PadIndex>,
    settings: CommandSettings,
    answer: Result<ReplyPayload, RequestError>,
) -> ServiceResponse {
    match (kind, answer) {
        (CommandKind::Tare, Ok(ReplyPayload::Ack)) => ServiceResponse::done(match pad {
            Some(pad) => format!(
                "tared pad {} over {} sample sets",
                pad.get(),
                settings.tare_sample_sets
            ),
            None => format!("tared over {} sample sets", settings.tare_sample_sets),
        }),
        (CommandKind::SetUseCase, Ok(ReplyPayload::ModelTier(tier))) => {
            ServiceResponse::done(format!("the device chose model tier {}", tier_words(tier)))
        }
        (_, Ok(_)) => ServiceResponse::failed("the device answered with a reply of another kind"),
        (_, Err(RequestError::Refused(code))) => ServiceResponse::failed(refusal_words(kind, code)),
        (_, Err(error)) => ServiceResponse::failed(error.to_string()),
    }
}

/// Why the device refused `kind`, for people.
fn refusal_words(kind: CommandKind, code: ErrorCode) -> String {
    let why = match (kind, code) {
        (_, ErrorCode::Busy) => "it is busy (a tare is already running)",
        (CommandKind::Tare, ErrorCode::TareNotStill) => {
            "a pad was not still (pressed or moving); tare again with the pads unloaded and at rest"
        }
        (CommandKind::Tare, ErrorCode::InvalidArgument) => {
            "it has no such pad (fewer pads than when the bridge opened it)"
        }
        (CommandKind::Tare, ErrorCode::TareFailed) => {
            "the tare finished without a baseline for every taxel (a pad was loaded, or a taxel is open or shorted)"
        }
        (CommandKind::SetUseCase, ErrorCode::InvalidArgument) => {
            "invalid use case (the pressure range and error budget must be above 0, the temperatures finite with the lowest below the highest)"
        }
        (CommandKind::SetUseCase, ErrorCode::NotSupported) => {
            "no model tier fits this use case with the calibration in use"
        }
        (_, ErrorCode::UnknownCommand) => "its firmware does not know this command",
        _ => "",
    };
    if why.is_empty() {
        format!("the device refused: {code:?}")
    } else {
        format!("the device refused: {why}")
    }
}

/// Replies `response` to `query` (and says so on the console).
impl PendingCall {
    /// Sends `response` as this call's reply.
    fn answer(&self, response: ServiceResponse, relay: &Relay) {
        let service = Service {
            device: self.device,
            kind: self.kind,
            pad: self.pad,
        };
        answer(
            &self.query,
            &self.key,
            &self.request,
            service,
            response,
            relay,
        );
    }
}

fn answer(
    query: &Query,
    key: &str,
    request: &Attachment,
    service: Service,
    response: ServiceResponse,
    relay: &Relay,
) {
    let device = service.device;
    let now_ns = i64::try_from(relay.now_ns()).unwrap_or(i64::MAX);
    let attachment = attachment(request.sequence_number, now_ns, &request.gid);
    let sent = query
        .reply(key, response.to_cdr())
        .attachment(attachment.to_vec())
        .wait();
    let outcome = if response.success { "done" } else { "not done" };
    match sent {
        Ok(()) => noteln!(
            "device {device}: {} from ROS 2 {outcome}: {}",
            service.words(),
            response.message
        ),
        Err(error) => noteln!(
            "device {device}: {} from ROS 2 {outcome} ({}), and the reply failed: {error}",
            service.words(),
            response.message
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SETTINGS: CommandSettings = CommandSettings {
        tare_sample_sets: 64,
        request_timeout: Duration::from_secs(2),
    };

    #[test]
    fn services_are_named_per_device() {
        assert_eq!(
            CommandKind::Tare.service_name("/taxel", 1),
            "/taxel/device1/tare"
        );
        assert_eq!(
            CommandKind::SetUseCase.service_name("/taxel/", 0),
            "/taxel/device0/set_use_case"
        );
        assert_eq!(
            CommandKind::Tare.pad_service_name("/taxel/", 1, PadIndex::new(3).unwrap()),
            "/taxel/device1/pad3/tare"
        );
        assert_eq!(
            SETTINGS.timeout(CommandKind::Tare),
            Duration::from_millis(5_200)
        );
    }

    #[test]
    fn requests_become_the_devices_commands() {
        assert_eq!(
            command_of(CommandKind::Tare, None, &[0, 1, 0, 0, 0], SETTINGS),
            Ok(Command::Tare {
                sample_sets: 64,
                pad: None
            })
        );
        assert_eq!(
            command_of(
                CommandKind::Tare,
                PadIndex::new(2),
                &[0, 1, 0, 0, 0],
                SETTINGS
            ),
            Ok(Command::Tare {
                sample_sets: 64,
                pad: PadIndex::new(2)
            })
        );
        let request = SetUseCaseRequest {
            pressure_max_kpa: 50.0,
            temperature_min_c: 15.0,
            temperature_max_c: 35.0,
            error_budget_kpa: 0.5,
        };
        assert_eq!(
            command_of(CommandKind::SetUseCase, None, &request.to_cdr(), SETTINGS),
            Ok(Command::SetUseCase(UseCase::GRIPPER))
        );
        let refused =
            command_of(CommandKind::SetUseCase, None, &[0, 1, 0, 0, 1], SETTINGS).unwrap_err();
        assert!(!refused.success);
        assert!(refused
            .message
            .starts_with("not a taxel_msgs/srv/SetUseCase request"));
    }

    #[test]
    fn the_devices_answers_become_responses() {
        let done = outcome(CommandKind::Tare, None, SETTINGS, Ok(ReplyPayload::Ack));
        assert_eq!(done, ServiceResponse::done("tared over 64 sample sets"));
        let pad = PadIndex::new(1);
        let done = outcome(CommandKind::Tare, pad, SETTINGS, Ok(ReplyPayload::Ack));
        assert_eq!(
            done,
            ServiceResponse::done("tared pad 1 over 64 sample sets")
        );
        let refused = outcome(
            CommandKind::Tare,
            pad,
            SETTINGS,
            Err(RequestError::Refused(ErrorCode::InvalidArgument)),
        );
        assert!(!refused.success && refused.message.contains("no such pad"));
        let chose = outcome(
            CommandKind::SetUseCase,
            None,
            SETTINGS,
            Ok(ReplyPayload::ModelTier(wire::Tier::Linear)),
        );
        assert!(chose.success && chose.message.starts_with("the device chose model tier"));
        let refused = outcome(
            CommandKind::Tare,
            None,
            SETTINGS,
            Err(RequestError::Refused(ErrorCode::TareNotStill)),
        );
        assert!(!refused.success && refused.message.contains("not still"));
        let timeout = outcome(
            CommandKind::SetUseCase,
            None,
            SETTINGS,
            Err(RequestError::Timeout {
                request_id: 3,
                timeout_ms: 2_000,
            }),
        );
        assert!(!timeout.success && timeout.message.contains("2000 ms"));
    }
}
