//! The ROS 2 domain id: `--ros2-domain`, else `ROS_DOMAIN_ID`, else 0.

use super::error::Ros2Error;

/// The largest domain id: DDS's port mapping (DDSI-RTPS 2.5 §9.6.1.1,
/// 7400 + 250 × domain + offsets) must stay within UDP's 65535; ROS 2's
/// docs give the same bound.
pub const MAX_DOMAIN: u32 = 232;

/// The domain to join: `asked` when given, else `ROS_DOMAIN_ID` when set
/// and not empty, else 0.
pub fn domain_id(asked: Option<u32>) -> Result<u16, Ros2Error> {
    let env = std::env::var("ROS_DOMAIN_ID").ok().filter(|v| !v.trim().is_empty());
    resolve(asked, env.as_deref())
}

fn resolve(asked: Option<u32>, env: Option<&str>) -> Result<u16, Ros2Error> {
    let domain = match (asked, env) {
        (Some(d), _) => d,
        (None, Some(v)) => v.trim().parse().map_err(|_| Ros2Error::DomainEnv { value: v.to_string() })?,
        (None, None) => 0,
    };
    match u16::try_from(domain) {
        Ok(d) if domain <= MAX_DOMAIN => Ok(d),
        _ => Err(Ros2Error::Domain { domain, max: MAX_DOMAIN }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_flag_wins_then_the_environment_then_zero() {
        assert_eq!(resolve(Some(7), Some("3")).unwrap(), 7);
        assert_eq!(resolve(None, Some(" 3 ")).unwrap(), 3);
        assert_eq!(resolve(None, None).unwrap(), 0);
        assert_eq!(resolve(Some(232), None).unwrap(), 232);
        assert!(matches!(resolve(Some(233), None), Err(Ros2Error::Domain { domain: 233, .. })));
        assert!(matches!(resolve(None, Some("x")), Err(Ros2Error::DomainEnv { .. })));
    }
}
