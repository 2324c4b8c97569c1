//! The one port error of every runtime process: what failed (send, notify,
//! receive), on which service, and iceoryx2's reason. The processes' own
//! error types wrap it (`#[from] PortError`), so a failed port reads the
//! same in every process's log.

use std::fmt::Debug;

/// A send, notification or receive on a run's port failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PortError {
    #[error("sending on `{service}` failed: {detail}")]
    Send {
        service: &'static str,
        detail: String,
    },
    #[error("notifying `{service}` failed: {detail}")]
    Notify {
        service: &'static str,
        detail: String,
    },
    #[error("receiving on `{service}` failed: {detail}")]
    Receive {
        service: &'static str,
        detail: String,
    },
}

impl PortError {
    pub fn send(service: &'static str, e: impl Debug) -> Self {
        Self::Send {
            service,
            detail: format!("{e:?}"),
        }
    }

    pub fn notify(service: &'static str, e: impl Debug) -> Self {
        Self::Notify {
            service,
            detail: format!("{e:?}"),
        }
    }

    pub fn receive(service: &'static str, e: impl Debug) -> Self {
        Self::Receive {
            service,
            detail: format!("{e:?}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_message_names_the_operation_and_the_service() {
        let e = PortError::send("ledger", "ExceedsMaxLoans");
        assert_eq!(
            e.to_string(),
            "sending on `ledger` failed: \"ExceedsMaxLoans\""
        );
        assert!(
            PortError::receive("slot", 3)
                .to_string()
                .starts_with("receiving on `slot`")
        );
        assert!(
            PortError::notify("agent wake", 3)
                .to_string()
                .starts_with("notifying `agent wake`")
        );
    }
}
