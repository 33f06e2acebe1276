//! The services the bridge serves (`taxel bridge --allow-commands`): `std_srvs/srv/Trigger`
//! (a device's tare) and `taxel_msgs/srv/SetUseCase` (ros2-messages/srv/SetUseCase.srv), with
//! their REP-2011 type descriptions (see [`crate::type_hash`]) and their requests and responses
//! in CDR.
//!
//! Both responses have the same two fields, `bool success` and `string message`:
//! [`ServiceResponse`] is either.

use crate::cdr::{CdrError, CdrReader, CdrWriter};
use crate::type_hash::{type_id, FieldDescription as Field, ServiceType, TypeDescription};
use crate::types::TIME;

/// `service_msgs/msg/ServiceEventInfo` (ROS 2 Iron and later): what every service's event
/// message starts with. Its `char[16] client_gid` is `uint8[16]` to rosidl (`char` is an alias
/// of `uint8` in `.msg` files).
pub static SERVICE_EVENT_INFO: TypeDescription = TypeDescription {
    type_name: "service_msgs/msg/ServiceEventInfo",
    fields: &[
        Field::primitive("event_type", type_id::UINT8),
        Field::nested("stamp", "builtin_interfaces/msg/Time"),
        Field::primitive_array("client_gid", type_id::UINT8, 16),
        Field::primitive("sequence_number", type_id::INT64),
    ],
};

/// `std_srvs/srv/Trigger_Request`: no field, so the placeholder every empty message gets.
pub static TRIGGER_REQUEST: TypeDescription = TypeDescription {
    type_name: "std_srvs/srv/Trigger_Request",
    fields: &[Field::primitive(
        "structure_needs_at_least_one_member",
        type_id::UINT8,
    )],
};

/// `std_srvs/srv/Trigger_Response`.
pub static TRIGGER_RESPONSE: TypeDescription = TypeDescription {
    type_name: "std_srvs/srv/Trigger_Response",
    fields: &[
        Field::primitive("success", type_id::BOOLEAN),
        Field::primitive("message", type_id::STRING),
    ],
};

/// `std_srvs/srv/Trigger_Event`.
pub static TRIGGER_EVENT: TypeDescription = TypeDescription {
    type_name: "std_srvs/srv/Trigger_Event",
    fields: &[
        Field::nested("info", "service_msgs/msg/ServiceEventInfo"),
        Field::nested_bounded_sequence("request", "std_srvs/srv/Trigger_Request", 1),
        Field::nested_bounded_sequence("response", "std_srvs/srv/Trigger_Response", 1),
    ],
};

/// `std_srvs/srv/Trigger` as a whole.
pub static TRIGGER: TypeDescription = TypeDescription {
    type_name: "std_srvs/srv/Trigger",
    fields: &[
        Field::nested("request_message", "std_srvs/srv/Trigger_Request"),
        Field::nested("response_message", "std_srvs/srv/Trigger_Response"),
        Field::nested("event_message", "std_srvs/srv/Trigger_Event"),
    ],
};

/// `std_srvs/srv/Trigger`: the tare service.
pub static TRIGGER_SERVICE: ServiceType = ServiceType {
    description: &TRIGGER,
    references: &[
        &TIME,
        &SERVICE_EVENT_INFO,
        &TRIGGER_REQUEST,
        &TRIGGER_RESPONSE,
        &TRIGGER_EVENT,
    ],
    definition: "---\nbool success   # indicate successful run of triggered service\nstring message # informational, e.g. for error messages\n",
};

/// `taxel_msgs/srv/SetUseCase_Request` (ros2-messages/srv/SetUseCase.srv).
pub static SET_USE_CASE_REQUEST: TypeDescription = TypeDescription {
    type_name: "taxel_msgs/srv/SetUseCase_Request",
    fields: &[
        Field::primitive("pressure_max_kpa", type_id::FLOAT),
        Field::primitive("temperature_min_c", type_id::FLOAT),
        Field::primitive("temperature_max_c", type_id::FLOAT),
        Field::primitive("error_budget_kpa", type_id::FLOAT),
    ],
};

/// `taxel_msgs/srv/SetUseCase_Response`.
pub static SET_USE_CASE_RESPONSE: TypeDescription = TypeDescription {
    type_name: "taxel_msgs/srv/SetUseCase_Response",
    fields: &[
        Field::primitive("success", type_id::BOOLEAN),
        Field::primitive("message", type_id::STRING),
    ],
};

/// `taxel_msgs/srv/SetUseCase_Event`.
pub static SET_USE_CASE_EVENT: TypeDescription = TypeDescription {
    type_name: "taxel_msgs/srv/SetUseCase_Event",
    fields: &[
        Field::nested("info", "service_msgs/msg/ServiceEventInfo"),
        Field::nested_bounded_sequence("request", "taxel_msgs/srv/SetUseCase_Request", 1),
        Field::nested_bounded_sequence("response", "taxel_msgs/srv/SetUseCase_Response", 1),
    ],
};

/// `taxel_msgs/srv/SetUseCase` as a whole.
pub static SET_USE_CASE: TypeDescription = TypeDescription {
    type_name: "taxel_msgs/srv/SetUseCase",
    fields: &[
        Field::nested("request_message", "taxel_msgs/srv/SetUseCase_Request"),
        Field::nested("response_message", "taxel_msgs/srv/SetUseCase_Response"),
        Field::nested("event_message", "taxel_msgs/srv/SetUseCase_Event"),
    ],
};

/// `taxel_msgs/srv/SetUseCase`: the device chooses its model tier for a use case.
pub static SET_USE_CASE_SERVICE: ServiceType = ServiceType {
    description: &SET_USE_CASE,
    references: &[
        &TIME,
        &SERVICE_EVENT_INFO,
        &SET_USE_CASE_REQUEST,
        &SET_USE_CASE_RESPONSE,
        &SET_USE_CASE_EVENT,
    ],
    definition: include_str!("../srv/SetUseCase.srv"),
};

/// Reads a `std_srvs/srv/Trigger` request: nothing but the encapsulation header matters (the
/// placeholder byte after it, if there, is ignored).
pub fn read_trigger_request(cdr: &[u8]) -> Result<(), CdrError> {
    CdrReader::new(cdr).map(|_| ())
}

/// The request of `taxel_msgs/srv/SetUseCase`: model-core's `UseCase`, field for field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetUseCaseRequest {
    /// Highest pressure of interest, kPa.
    pub pressure_max_kpa: f32,
    /// Lowest pad temperature expected, °C.
    pub temperature_min_c: f32,
    /// Highest pad temperature expected, °C.
    pub temperature_max_c: f32,
    /// Largest acceptable error, kPa.
    pub error_budget_kpa: f32,
}

impl SetUseCaseRequest {
    /// Reads a serialised request.
    pub fn from_cdr(cdr: &[u8]) -> Result<Self, CdrError> {
        let mut reader = CdrReader::new(cdr)?;
        Ok(Self {
            pressure_max_kpa: reader.read_f32()?,
            temperature_min_c: reader.read_f32()?,
            temperature_max_c: reader.read_f32()?,
            error_budget_kpa: reader.read_f32()?,
        })
    }

    /// The serialised request, as a ROS 2 client sends it.
    pub fn to_cdr(&self) -> Vec<u8> {
        let mut writer = CdrWriter::new();
        writer.write_f32(self.pressure_max_kpa);
        writer.write_f32(self.temperature_min_c);
        writer.write_f32(self.temperature_max_c);
        writer.write_f32(self.error_budget_kpa);
        writer.finish()
    }
}

/// The response of `std_srvs/srv/Trigger` and of `taxel_msgs/srv/SetUseCase` (the same
/// fields).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ServiceResponse {
    /// Whether the device did it.
    pub success: bool,
    /// What it did, or why not.
    pub message: String,
}

impl ServiceResponse {
    /// A success saying `message`.
    pub fn done(message: impl Into<String>) -> Self {
        Self {
            success: true,
            message: message.into(),
        }
    }

    /// A failure saying why.
    pub fn failed(message: impl Into<String>) -> Self {
        Self {
            success: false,
            message: message.into(),
        }
    }

    /// The serialised response.
    pub fn to_cdr(&self) -> Vec<u8> {
        let mut writer = CdrWriter::new();
        writer.write_bool(self.success);
        writer.write_string(&self.message);
        writer.finish()
    }

    /// Reads a serialised response.
    pub fn from_cdr(cdr: &[u8]) -> Result<Self, CdrError> {
        let mut reader = CdrReader::new(cdr)?;
        Ok(Self {
            success: reader.read_bool()?,
            message: reader.read_string()?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::type_hash::MessageType;

    fn message_hash(
        description: &'static TypeDescription,
        references: &'static [&'static TypeDescription],
    ) -> String {
        MessageType {
            description,
            references,
            definition: "",
        }
        .type_hash()
    }

    static INFO_REFERENCES: [&TypeDescription; 1] = [&TIME];
    static EVENT_REFERENCES: [&TypeDescription; 4] = [
        &TIME,
        &SERVICE_EVENT_INFO,
        &TRIGGER_REQUEST,
        &TRIGGER_RESPONSE,
    ];

    // Literal hashes of ROS 2 Jazzy's generated std_srvs and service_msgs (share/std_srvs/srv/
    // Trigger.json): the same literals are in the golden tests of several public ROS 2
    // projects. rosidl maps `char` to `uint8`, so ServiceEventInfo's `char[16] client_gid` is a
    // uint8 array (rosbags 0.11 hashes it as char, and gets another hash for it).
    #[test]
    fn trigger_hashes_equal_those_rosidl_generates() {
        assert_eq!(
            message_hash(&SERVICE_EVENT_INFO, &INFO_REFERENCES),
            "RIHS01_41bcbbe07a75c9b52bc96bfd5c24d7f0fc0a08c0cb7921b3373c5732345a6f45"
        );
        assert_eq!(
            message_hash(&TRIGGER_REQUEST, &[]),
            "RIHS01_d010825374ce8918e72bfd826c82603e60f45419e932ea976f807b74a863a199"
        );
        assert_eq!(
            message_hash(&TRIGGER_EVENT, &EVENT_REFERENCES),
            "RIHS01_ec4a1d26b0575e61906890342aba9523a2360e9845857c5590fa6e23bc39e1c2"
        );
        assert_eq!(
            TRIGGER_SERVICE.type_hash(),
            "RIHS01_eeff2cd6fa5ad9d27cdf4dec64818317839b62f212a91e6b5304b634b2062c5f"
        );
        // Not published anywhere: rosbags' RIHS01 of the fields of srv/SetUseCase.srv, composed as
        // above (bridge/tests/python/call_services.py computes it again from the file).
        assert_eq!(
            SET_USE_CASE_SERVICE.type_hash(),
            "RIHS01_760a9d7bc0c5f0224429a1624f490f9032a2534cc7187b81c4523c474f85ccda"
        );
        assert_eq!(
            TRIGGER_SERVICE.dds_type_name(),
            "std_srvs::srv::dds_::Trigger_"
        );
        assert_eq!(
            SET_USE_CASE_SERVICE.dds_type_name(),
            "taxel_msgs::srv::dds_::SetUseCase_"
        );
    }

    /// The `.srv` file in the repository and the description hashed are the same fields.
    #[test]
    fn the_srv_file_declares_the_fields_hashed() {
        let fields = |part: &str| -> Vec<(String, String)> {
            part.lines()
                .map(|line| line.split('#').next().unwrap_or("").trim())
                .filter(|line| !line.is_empty())
                .map(|line| {
                    let (kind, name) = line.split_once(' ').unwrap();
                    (kind.to_owned(), name.trim().to_owned())
                })
                .collect()
        };
        let (request, response) = SET_USE_CASE_SERVICE
            .definition
            .split_once("\n---\n")
            .unwrap();
        let described = |description: &TypeDescription| -> Vec<(String, String)> {
            description
                .fields
                .iter()
                .map(|field| {
                    let kind = match field.type_id {
                        type_id::FLOAT => "float32",
                        type_id::BOOLEAN => "bool",
                        type_id::STRING => "string",
                        other => panic!("type {other}"),
                    };
                    (kind.to_owned(), field.name.to_owned())
                })
                .collect()
        };
        assert_eq!(fields(request), described(&SET_USE_CASE_REQUEST));
        assert_eq!(fields(response), described(&SET_USE_CASE_RESPONSE));
    }

    #[test]
    fn requests_and_responses_round_trip() {
        let request = SetUseCaseRequest {
            pressure_max_kpa: 50.0,
            temperature_min_c: 15.0,
            temperature_max_c: 35.0,
            error_budget_kpa: 0.5,
        };
        let bytes = request.to_cdr();
        assert_eq!(bytes.len(), 4 + 16);
        assert_eq!(SetUseCaseRequest::from_cdr(&bytes), Ok(request));
        assert!(SetUseCaseRequest::from_cdr(&bytes[..10]).is_err());
        let response = ServiceResponse::failed("no");
        assert_eq!(
            response.to_cdr(),
            [0, 1, 0, 0, 0, 0, 0, 0, 3, 0, 0, 0, b'n', b'o', 0]
        );
        assert_eq!(ServiceResponse::from_cdr(&response.to_cdr()), Ok(response));
        assert_eq!(read_trigger_request(&[0, 1, 0, 0, 0]), Ok(()));
    }
}
