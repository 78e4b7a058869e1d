//! The last step of [`super::read_mission_with`]: the topics read become
//! one [`Mission`], with the mounting from the static transforms when the
//! input has no echofield metadata, and a [`ChannelUse`] per topic.

use super::{
    ChannelUse, Decoder, ROLES, STREAM_NAMES, STREAMS, TF, TF_STATIC, Topic, TopicChoice,
    chosen_elsewhere, resorted, stream_of,
};
use crate::ros::messages::{Decoded, MessageType, Stream, Transform};
use crate::ros::tf;
use echofield_frontend::sensors::Mission;

/// What every topic's use is judged against.
pub(super) struct TopicContext<'a> {
    /// The topic chosen for each stream (in [`ROLES`] order).
    pub chosen: &'a [Option<String>; STREAMS],
    pub choice: &'a TopicChoice,
    /// The `/tf` frame pairs that never changed.
    pub constant_tf: &'a [Transform],
    /// How many `/tf` frame pairs there were.
    pub tf_pairs: usize,
}

/// The frames whose mountings are looked up in the static transforms.
pub(super) struct Frames {
    /// `header.frame_id` of the sonar and DVL topics, when they name one.
    pub sonar: Option<String>,
    pub dvl: Option<String>,
    /// The topic chosen for the DVL.
    pub dvl_topic: Option<String>,
}

/// The records of the used topics, gathered in topic order.
#[derive(Default)]
pub(super) struct Gathered {
    pub mission: Mission,
    pub uses: Vec<ChannelUse>,
    /// The transforms of `/tf_static`.
    pub static_transforms: Vec<Transform>,
    /// Index in `uses` of `/tf_static`, and of `/tf` when some of its pairs
    /// never change.
    pub tf_use: Option<usize>,
    pub tf_dynamic_use: Option<usize>,
}

impl Gathered {
    /// Adds the records of `topic` to the stream it was chosen for (the
    /// transforms of `/tf_static` to `static_transforms`) and records its
    /// use.
    pub fn add_topic(&mut self, name: String, topic: Topic, context: &TopicContext) {
        let used = (0..STREAMS)
            .find(|&s| context.chosen[s].as_deref() == Some(name.as_str()))
            .map(stream_of);
        let is_tf = matches!(topic.decoder, Some(Decoder::Ros(MessageType::TfMessage, _)));
        let reason = reason(&name, &topic, used, is_tf, context);
        for record in topic.records {
            match (record, used) {
                (Decoded::Transforms(t), _) if is_tf && name == TF_STATIC => {
                    self.static_transforms.extend(t)
                }
                (_, None) => {}
                (Decoded::Beams(b), _) => self.mission.beams.extend(b),
                (Decoded::Dvl(d), _) => self.mission.dvl.push(d),
                (Decoded::Attitude(a), _) => self.mission.attitude.push(a),
                (Decoded::GroundTruth(g), _) => self.mission.ground_truth.push(g),
                (Decoded::PositionFix(f), _) => self.mission.position_fixes.push(f),
                (Decoded::Odometry(_, d), Some(Stream::Dvl)) => self.mission.dvl.push(d),
                (Decoded::Odometry(g, _), _) => self.mission.ground_truth.push(g),
                (Decoded::Transforms(_), _) => {}
            }
        }
        if is_tf && name == TF_STATIC {
            self.tf_use = Some(self.uses.len());
        }
        if is_tf && name == TF && !context.constant_tf.is_empty() {
            self.tf_dynamic_use = Some(self.uses.len());
        }
        self.uses.push(ChannelUse {
            topic: name,
            schema: topic.schema,
            role: used.map(|s| ROLES[s as usize]),
            reason,
            messages: topic.messages,
        });
    }
}

/// Why a topic was used (`used`: the stream it feeds) or skipped; empty
/// for `/tf_static`, whose reason the mounting lookup writes.
fn reason(
    name: &str,
    topic: &Topic,
    used: Option<Stream>,
    is_tf: bool,
    context: &TopicContext,
) -> String {
    let default_stream = topic.decoder.and_then(Decoder::stream);
    match (used, default_stream) {
        (Some(s), _) if context.choice.topics[s as usize].is_some() => {
            format!("chosen with --topic {}", ROLES[s as usize])
        }
        (Some(_), _) => "the only topic of its type".to_string(),
        (None, Some(s)) if chosen_elsewhere(context.choice, name, s as usize) => {
            "chosen for another role".to_string()
        }
        (None, Some(s)) => format!(
            "another topic feeds the {} (`{}`)",
            STREAM_NAMES[s as usize],
            context.chosen[s as usize].as_deref().unwrap_or("")
        ),
        (None, None) if is_tf && name == TF_STATIC => String::new(),
        (None, None) if is_tf && name == TF && !context.constant_tf.is_empty() => format!(
            "{} of its {} frame pairs never change: read as static transforms",
            context.constant_tf.len(),
            context.tf_pairs
        ),
        (None, None) if is_tf => format!(
            "dynamic transforms are not read (the mountings come from {TF_STATIC}, or from {TF} pairs that never change)"
        ),
        (None, None) if topic.schema.is_empty() => "no schema".to_string(),
        (None, None) => format!("type `{}` is not one echofield reads", topic.schema),
    }
}

/// The static transforms followed by the `/tf` pairs that never change,
/// except those whose child `/tf_static` has (it wins; frame names compared
/// without a leading `/`).
pub(super) fn with_constant(
    mut static_transforms: Vec<Transform>,
    constant_tf: Vec<Transform>,
) -> Vec<Transform> {
    let strip = |f: &str| f.trim_start_matches('/').to_string();
    let static_children: Vec<String> = static_transforms.iter().map(|t| strip(&t.child)).collect();
    static_transforms.extend(
        constant_tf
            .into_iter()
            .filter(|t| !static_children.contains(&strip(&t.child))),
    );
    static_transforms
}

/// The mission whose mounting is looked up, the topic uses and the index
/// in them of the transform topic that gives it.
pub(super) struct MountingTarget<'a> {
    pub mission: &'a mut Mission,
    pub uses: &'a mut [ChannelUse],
    pub tf_use: usize,
}

impl MountingTarget<'_> {
    /// The sonar's mounting (and the DVL's position and yaw on the vehicle,
    /// for the dead reckoning's lever-arm compensation) from `transforms`;
    /// the transform topic's use says what was found or why the mounting
    /// stays unknown.
    pub fn mount_from(self, transforms: &[Transform], frames: &Frames) {
        let i = self.tf_use;
        let found = frames
            .sonar
            .as_deref()
            .and_then(|f| tf::mounting_of(transforms, f));
        let sonar = match (&found, frames.sonar.as_deref()) {
            (Some(m), _) => {
                self.mission.mounting = m.apply(&self.mission.mounting);
                self.uses[i].role = Some("mounting");
                m.describe()
            }
            (None, Some(frame)) => format!(
                "no static transform has the sonar frame `{frame}` as child: mounting unknown"
            ),
            (None, None) => "no sonar topic names its frame: mounting unknown".into(),
        };
        self.uses[i].reason = if self.uses[i].reason.is_empty() {
            sonar
        } else {
            format!("{}; {sonar}", self.uses[i].reason)
        };
        let dvl = frames
            .dvl
            .as_deref()
            .and_then(|f| tf::mounting_of(transforms, f));
        if let (Some(m), Some(topic)) = (dvl, frames.dvl_topic.as_deref()) {
            self.mission.mounting.vehicle_from_dvl = m.vehicle_from_frame;
            self.uses[i].role = Some("mounting");
            self.uses[i].reason = format!("{}; {}", self.uses[i].reason, m.describe_dvl());
            if let Some(u) = self.uses.iter_mut().find(|u| u.topic == topic) {
                u.reason = format!("{}; {}", u.reason, m.describe_dvl());
            }
        }
    }
}

/// Sorts each stream by stamp. Stable sorts: equal stamps keep their file
/// order. Records that went backwards are counted first (a warning for the
/// report).
pub(super) fn sort_streams(mission: &mut Mission) {
    let streams = [
        resorted(STREAM_NAMES[0], mission.beams.iter().map(|b| b.stamp_s)),
        resorted(STREAM_NAMES[1], mission.dvl.iter().map(|d| d.stamp_s)),
        resorted(STREAM_NAMES[2], mission.attitude.iter().map(|a| a.stamp_s)),
        resorted(
            STREAM_NAMES[3],
            mission.ground_truth.iter().map(|g| g.stamp_s),
        ),
        resorted(
            STREAM_NAMES[4],
            mission.position_fixes.iter().map(|f| f.stamp_s),
        ),
    ];
    mission.warnings.extend(streams.into_iter().flatten());
    mission
        .beams
        .sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
    mission.dvl.sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
    mission
        .attitude
        .sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
    mission
        .ground_truth
        .sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
    mission
        .position_fixes
        .sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
}
