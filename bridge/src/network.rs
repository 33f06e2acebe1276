//! The bridge's Zenoh session: by default it behaves like an rmw_zenoh node (it connects to the
//! router on this machine, keeps trying quietly while there is none, and does not scout by
//! multicast) and listens on loopback only, at a fixed port, for a plain Zenoh subscriber on this
//! machine. Nothing outside the machine can reach it unless the user says so: `--listen` on
//! another interface, `--multicast-scouting`, or a Zenoh configuration file.

use std::path::PathBuf;

/// rmw_zenoh's router on this machine, where ROS 2 nodes meet (`ros2 run rmw_zenoh_cpp
/// rmw_zenohd` listens there).
pub const DEFAULT_ROUTER: &str = "tcp/localhost:7447";

/// Where the bridge listens by default: loopback only, one port above the router's, so a plain
/// Zenoh subscriber on this machine can connect to it without a router.
pub const DEFAULT_LISTEN: &str = "tcp/127.0.0.1:7448";

/// The Zenoh session's network options. A `None` takes the bridge's default, or, with a
/// configuration file, the file's value.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Network {
    /// Endpoints to listen on (default: [`DEFAULT_LISTEN`]).
    pub listen: Option<Vec<String>>,
    /// Endpoints to connect to, retried until they answer (default: [`DEFAULT_ROUTER`]).
    pub connect: Option<Vec<String>>,
    /// Find and be found by other Zenoh sessions by UDP multicast (default: off, as rmw_zenoh).
    pub multicast_scouting: Option<bool>,
    /// A Zenoh configuration file (JSON5) the options above are applied on top of.
    pub config_file: Option<PathBuf>,
}

impl Network {
    /// The Zenoh configuration: the file's (or Zenoh's defaults), then the bridge's defaults
    /// where there is no file, then the options given.
    pub fn zenoh_config(&self) -> anyhow::Result<zenoh::Config> {
        let error = |error: zenoh::Error| anyhow::anyhow!("zenoh configuration: {error}");
        let mut config = match &self.config_file {
            Some(path) => zenoh::Config::from_file(path).map_err(error)?,
            None => zenoh::Config::default(),
        };
        let defaults = self.config_file.is_none();
        let mut set = |key: &str, value: String| config.insert_json5(key, &value).map_err(error);
        if let Some(listen) = self.listen_endpoints(defaults) {
            set("listen/endpoints", json_list(&listen))?;
        }
        if let Some(connect) = self.connect_endpoints(defaults) {
            set("connect/endpoints", json_list(&connect))?;
            // A peer tries its endpoints until they answer and never gives up (rmw_zenoh's
            // setting): the bridge starts before the router, or keeps running while it restarts.
            set("connect/timeout_ms", "-1".to_owned())?;
            set("connect/exit_on_failure", "false".to_owned())?;
        }
        if let Some(multicast) = self.multicast(defaults) {
            set("scouting/multicast/enabled", multicast.to_string())?;
        }
        Ok(config)
    }

    /// What the session is exposed on, for the start-up line.
    pub fn describe(&self) -> String {
        let defaults = self.config_file.is_none();
        let from_file = |what: &str| format!("{what} as in the Zenoh configuration file");
        let listen = match self.listen_endpoints(defaults) {
            Some(endpoints) if endpoints.is_empty() => "listening nowhere".to_owned(),
            Some(endpoints) => format!("listening on {}", endpoints.join(", ")),
            None => from_file("listening"),
        };
        let connect = match self.connect_endpoints(defaults) {
            Some(endpoints) if endpoints.is_empty() => "connecting nowhere".to_owned(),
            Some(endpoints) => format!("connecting to {} (retried)", endpoints.join(", ")),
            None => from_file("connecting"),
        };
        let multicast = match self.multicast(defaults) {
            Some(true) => "multicast scouting on".to_owned(),
            Some(false) => "multicast scouting off".to_owned(),
            None => from_file("multicast scouting"),
        };
        format!("{listen}, {connect}, {multicast}")
    }

    fn listen_endpoints(&self, defaults: bool) -> Option<Vec<String>> {
        self.listen
            .clone()
            .or_else(|| defaults.then(|| vec![DEFAULT_LISTEN.to_owned()]))
    }

    fn connect_endpoints(&self, defaults: bool) -> Option<Vec<String>> {
        self.connect
            .clone()
            .or_else(|| defaults.then(|| vec![DEFAULT_ROUTER.to_owned()]))
    }

    fn multicast(&self, defaults: bool) -> Option<bool> {
        self.multicast_scouting.or(defaults.then_some(false))
    }
}

fn json_list(endpoints: &[String]) -> String {
    let quoted: Vec<String> = endpoints
        .iter()
        .map(|endpoint| format!("{endpoint:?}"))
        .collect();
    format!("[{}]", quoted.join(","))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn value(config: &zenoh::Config, key: &str) -> String {
        config.get_json(key).unwrap()
    }

    #[test]
    fn by_default_loopback_only_the_local_router_and_no_multicast() {
        let config = Network::default().zenoh_config().unwrap();
        assert_eq!(
            value(&config, "listen/endpoints"),
            r#"["tcp/127.0.0.1:7448"]"#
        );
        assert_eq!(
            value(&config, "connect/endpoints"),
            r#"["tcp/localhost:7447"]"#
        );
        assert_eq!(value(&config, "scouting/multicast/enabled"), "false");
    }

    #[test]
    fn options_replace_the_defaults() {
        let network = Network {
            listen: Some(vec!["tcp/0.0.0.0:9000".to_owned()]),
            connect: Some(Vec::new()),
            multicast_scouting: Some(true),
            config_file: None,
        };
        let config = network.zenoh_config().unwrap();
        assert_eq!(
            value(&config, "listen/endpoints"),
            r#"["tcp/0.0.0.0:9000"]"#
        );
        assert_eq!(value(&config, "connect/endpoints"), "[]");
        assert_eq!(value(&config, "scouting/multicast/enabled"), "true");
        assert_eq!(
            network.describe(),
            "listening on tcp/0.0.0.0:9000, connecting nowhere, multicast scouting on"
        );
    }

    #[test]
    fn a_configuration_file_keeps_what_the_options_do_not_give() {
        let directory = tempfile::tempdir().unwrap();
        let path = directory.path().join("zenoh.json5");
        std::fs::write(
            &path,
            r#"{ listen: { endpoints: ["tcp/127.0.0.1:9100"] }, scouting: { multicast: { enabled: true } } }"#,
        )
        .unwrap();
        let network = Network {
            connect: Some(vec!["tcp/10.0.0.2:7447".to_owned()]),
            config_file: Some(path),
            ..Network::default()
        };
        let config = network.zenoh_config().unwrap();
        assert_eq!(
            value(&config, "listen/endpoints"),
            r#"["tcp/127.0.0.1:9100"]"#
        );
        assert_eq!(
            value(&config, "connect/endpoints"),
            r#"["tcp/10.0.0.2:7447"]"#
        );
        assert_eq!(value(&config, "scouting/multicast/enabled"), "true");
    }

    #[test]
    fn the_access_control_examples_of_the_bridge_document_are_valid_configurations() {
        let document = include_str!("../../docs/BRIDGE.md");
        let blocks: Vec<&str> = document
            .split("```json5\n")
            .skip(1)
            .map(|rest| &rest[..rest.find("```").unwrap()])
            .collect();
        assert_eq!(
            blocks.len(),
            2,
            "the pads' readers and the services' callers"
        );
        let directory = tempfile::tempdir().unwrap();
        for (index, block) in blocks.iter().enumerate() {
            let path = directory.path().join(format!("acl{index}.json5"));
            std::fs::write(&path, block).unwrap();
            let network = Network {
                config_file: Some(path),
                ..Network::default()
            };
            let config = network.zenoh_config().unwrap();
            assert_eq!(value(&config, "access_control/enabled"), "true");
            assert_eq!(
                value(&config, "listen/endpoints"),
                r#"["tcp/0.0.0.0:7448"]"#
            );
            assert_eq!(
                network.describe(),
                "listening as in the Zenoh configuration file, connecting as in the Zenoh configuration file, multicast scouting as in the Zenoh configuration file"
            );
        }
        assert!(blocks
            .iter()
            .any(|block| block.contains("\"query\", \"reply\"")
                && block.contains("0/taxel/*/tare/**")));
    }
}
