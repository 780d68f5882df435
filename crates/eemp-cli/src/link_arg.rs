//! `--link`, `--iface`, `--domain`: which low-level interface `eemp hw` and `eemp sim-robot`
//! speak. The robot file's `sdk.protocol` decides by default (the A1: UDP, the Go2: DDS); a
//! link the robot does not speak is refused, naming both.

use eemp_core::robot::{LowLevelProtocol, RobotConfig};
use eemp_hw::dds::DdsConfig;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LinkKind {
    /// The A1's legacy UDP datagrams (unitree_legged_sdk 3.3).
    Udp,
    /// The Go2's DDS topics rt/lowcmd / rt/lowstate (unitree_sdk2).
    Dds,
}

impl LinkKind {
    fn name(self) -> &'static str {
        match self {
            LinkKind::Udp => "udp",
            LinkKind::Dds => "dds",
        }
    }
}

#[derive(clap::Args, Debug, Clone)]
pub struct LinkArgs {
    /// udp (the A1) or dds (the Go2); default: what the robot file's sdk.protocol says.
    #[arg(long, value_enum)]
    pub link: Option<LinkKind>,
    /// DDS only: the network interface to speak on (the robot's: e.g. enp3s0; loopback: lo).
    /// Default: every interface (hw), lo (sim-robot).
    #[arg(long)]
    pub iface: Option<String>,
    /// DDS only: the domain id, 0..=232. Default: 0 (hw, the robot's), 1 (sim-robot, as
    /// Unitree's simulator).
    #[arg(long)]
    pub domain: Option<u16>,
}

/// The link to use, with its DDS settings.
#[derive(Clone, Debug, PartialEq)]
pub enum Resolved {
    Udp,
    Dds(DdsConfig),
}

impl LinkArgs {
    /// `default_domain` / `default_iface`: this command's DDS defaults.
    pub fn resolve(
        &self,
        robot: &RobotConfig,
        default_domain: u16,
        default_iface: Option<&str>,
    ) -> Result<Resolved, String> {
        let spoken = match robot.sdk.protocol {
            LowLevelProtocol::A1Udp => Some(LinkKind::Udp),
            LowLevelProtocol::Go2Dds => Some(LinkKind::Dds),
            LowLevelProtocol::None => None,
        };
        let Some(spoken) = spoken else {
            return Err(format!(
                "robot '{}' speaks '{}' (sdk.protocol): no low-level codec the project could \
                 check against the real robot (the Go1's UDP format is known only from \
                 reverse engineering); simulate it with eemp walk / stand --robot instead",
                robot.name,
                robot.sdk.protocol.name()
            ));
        };
        let kind = self.link.unwrap_or(spoken);
        if kind != spoken {
            return Err(format!(
                "--link {} does not fit robot '{}': it speaks '{}' (sdk.protocol), i.e. --link {}",
                kind.name(),
                robot.name,
                robot.sdk.protocol.name(),
                spoken.name()
            ));
        }
        match kind {
            LinkKind::Udp => {
                if self.iface.is_some() || self.domain.is_some() {
                    return Err(
                        "--iface and --domain are DDS settings: the UDP link takes --address and --bind"
                            .into(),
                    );
                }
                Ok(Resolved::Udp)
            }
            LinkKind::Dds => {
                let dds = DdsConfig {
                    domain_id: self.domain.unwrap_or(default_domain),
                    iface: self.iface.clone().or(default_iface.map(str::to_owned)),
                };
                dds.validate()?;
                Ok(Resolved::Dds(dds))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn go2() -> RobotConfig {
        RobotConfig::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../robots/go2.toml"
        )))
        .unwrap()
    }

    fn args(link: Option<LinkKind>, domain: Option<u16>) -> LinkArgs {
        LinkArgs {
            link,
            iface: None,
            domain,
        }
    }

    #[test]
    fn the_robot_file_picks_the_link_and_a_mismatch_is_refused_naming_both() {
        let a1 = RobotConfig::a1();
        let r = args(None, None).resolve(&a1, 0, None).unwrap();
        assert_eq!(r, Resolved::Udp);
        let r = args(None, None).resolve(&go2(), 1, Some("lo")).unwrap();
        assert_eq!(
            r,
            Resolved::Dds(DdsConfig {
                domain_id: 1,
                iface: Some("lo".into())
            })
        );
        let e = args(Some(LinkKind::Udp), None)
            .resolve(&go2(), 0, None)
            .err()
            .unwrap();
        assert!(
            e.contains("--link udp") && e.contains("'go2'") && e.contains("--link dds"),
            "{e}"
        );
        let e = args(Some(LinkKind::Dds), None)
            .resolve(&a1, 0, None)
            .err()
            .unwrap();
        assert!(e.contains("'a1'") && e.contains("a1-udp"), "{e}");
        let e = args(None, Some(3)).resolve(&a1, 0, None).err().unwrap();
        assert!(e.contains("--domain"), "{e}");
        let e = args(None, Some(300))
            .resolve(&go2(), 0, None)
            .err()
            .unwrap();
        assert!(e.contains("300") && e.contains("0..=232"), "{e}");
    }
}
