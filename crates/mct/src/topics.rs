//! The shape of the topics the embedded broker takes: at most [`MAX_TOPIC_LEVELS`] levels and
//! [`MAX_TOPIC_BYTES`] bytes, for topic names (PUBLISH, a last will) and filters (SUBSCRIBE)
//! alike, checked before anything of the broker walks a topic tree with them.
//!
//! rmqtt keeps subscriptions and retained messages in trees with one node a level, and walks
//! them level by level; as published, some of those walks recurse once a level, so one packet
//! with a topic of a few thousand levels (a SUBSCRIBE of 6,000, a retained PUBLISH of 8,000)
//! overflowed a broker thread's stack and aborted the PLC's whole process. Cetratus's own topics
//! have fewer than 8 levels (`cetratus/<plc>/reply/<client>/<id>`), and common plant topics (ISA-95
//! paths, Sparkplug) fewer than 16; 128 levels and 4 KiB leave room for any of them, and keep
//! every walk of the trees short.

/// Levels (the parts between `/`) that a topic name or filter may have.
pub const MAX_TOPIC_LEVELS: usize = 128;

/// Bytes that a topic name or filter may have.
pub const MAX_TOPIC_BYTES: usize = 4 << 10;

/// Why a topic is refused, for the log and the client's reason string.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TopicRefusal {
    /// More than [`MAX_TOPIC_LEVELS`] levels.
    #[error("the topic has {levels} levels; the embedded broker takes at most {MAX_TOPIC_LEVELS}")]
    TooDeep {
        /// The levels counted, up to one past the limit.
        levels: usize,
    },
    /// More than [`MAX_TOPIC_BYTES`] bytes.
    #[error("the topic has {bytes} bytes; the embedded broker takes at most {MAX_TOPIC_BYTES}")]
    TooLong {
        /// Its length in bytes.
        bytes: usize,
    },
}

/// Checks `topic` against [`MAX_TOPIC_BYTES`] and [`MAX_TOPIC_LEVELS`]; counts no further than
/// one level past the limit, so a refused topic costs no more than a taken one.
pub fn check_topic(topic: &str) -> Result<(), TopicRefusal> {
    if topic.len() > MAX_TOPIC_BYTES {
        return Err(TopicRefusal::TooLong { bytes: topic.len() });
    }
    let levels = topic.split('/').take(MAX_TOPIC_LEVELS + 1).count();
    if levels > MAX_TOPIC_LEVELS {
        return Err(TopicRefusal::TooDeep { levels });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_topic_within_both_limits_passes_and_one_over_either_is_refused() {
        let deepest = vec!["a"; MAX_TOPIC_LEVELS].join("/");
        assert_eq!(check_topic(&deepest), Ok(()));
        assert_eq!(check_topic("cetratus/cell1/cmd/load"), Ok(()));
        assert_eq!(
            check_topic(&format!("{deepest}/b")),
            Err(TopicRefusal::TooDeep {
                levels: MAX_TOPIC_LEVELS + 1
            })
        );
        assert_eq!(
            check_topic(&"/".repeat(MAX_TOPIC_LEVELS)),
            Err(TopicRefusal::TooDeep {
                levels: MAX_TOPIC_LEVELS + 1
            }),
            "empty levels count"
        );
        let longest = "x".repeat(MAX_TOPIC_BYTES);
        assert_eq!(check_topic(&longest), Ok(()));
        assert_eq!(
            check_topic(&format!("{longest}y")),
            Err(TopicRefusal::TooLong {
                bytes: MAX_TOPIC_BYTES + 1
            })
        );
    }
}
