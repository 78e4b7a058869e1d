//! `echofield convert`: real logs into echofield MCAP missions.

use anyhow::{Context, Result};
use echofield_datasets::mcap::{TopicChoice, read_mission_with, write_mission};
use echofield_datasets::miniking::read_miniking_bag;
use echofield_datasets::ping360::read_ping360;
use echofield_datasets::sonar_recording::SonarRecording;
use echofield_datasets::stpere::keyframes::KeyframeBeams;
use echofield_datasets::stpere::{
    MARINA_YAW_OFFSET_RAD, StPereLogs, read_stpere_dir, read_stpere_with_keyframes,
};
use echofield_frontend::sensors::SweepTiming;
use echofield_graph::wrap_angle;
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Subcommand)]
pub enum Args {
    /// Girona St Pere marina logs (DVL, MTi, DGPS, sonar setup and beams).
    #[command(after_help = STPERE_EXAMPLES)]
    Stpere(StPereArgs),
    /// A Blue Robotics Ping360 log written by Ping Viewer (.bin): beams only.
    #[command(after_help = PING360_EXAMPLES)]
    Ping360(SonarArgs),
    /// A ROS 1 bag with Tritech MiniKing miniking_ros/AcousticBeam messages:
    /// beams only.
    #[command(after_help = MINIKING_EXAMPLES)]
    Miniking(SonarArgs),
    /// A ROS recording with standard messages: a ROS 2 MCAP file, a
    /// rosbag2 folder (MCAP or sqlite3 storage) or a ROS 1 bag; the sonar
    /// and DVL mountings from /tf_static.
    #[command(after_help = ROS_EXAMPLES)]
    Ros(RosArgs),
}

const ROS_EXAMPLES: &str = "\
Examples:
  echofield convert ros my_rosbag2_folder --output mission.mcap
  echofield convert ros full_dataset.bag --topic sonar=/sonar_micron --topic heading=/imu_adis_ros \\
    --output caves.mcap

Read types: sonar ping360_sonar_msgs/SonarEcho, ping360_sonar/SonarEcho (ROS 1),
marine_acoustic_msgs/RawSonarImage, sensor_msgs/LaserScan, echofield_msgs/SonarBeam,
cirs_girona_cala_viuda/RangeImageBeam; DVL marine_acoustic_msgs/Dvl, dvl_msgs/DVL,
waterlinked_a50_ros_driver/DVL, cirs_girona_cala_viuda/LinkquestDvl,
geometry_msgs/TwistWithCovarianceStamped, nav_msgs/Odometry (its twist, when chosen);
heading sensor_msgs/Imu, geometry_msgs/QuaternionStamped; ground truth
nav_msgs/Odometry, geometry_msgs/PoseStamped. Each topic's use is printed.";

#[derive(Debug, clap::Args)]
pub struct RosArgs {
    /// The recording: MCAP file, rosbag2 folder or ROS 1 bag.
    pub input: PathBuf,
    /// Output MCAP file (written atomically).
    #[arg(short, long)]
    pub output: PathBuf,
    /// The topic of a role, `ROLE=/name` (roles: sonar, dvl, heading,
    /// ground_truth, position_fix); needed where several topics carry a role's types.
    #[arg(long = "topic", value_name = "ROLE=/NAME", value_parser = TopicChoice::parse_assignment)]
    pub topics: Vec<(usize, String)>,
}

const STPERE_EXAMPLES: &str = "\
Examples:
  # The heading calibration fitted against DGPS on the marina (+19.4 deg)
  # goes into the mission's mounting; the MTi yaw is written as logged:
  echofield convert stpere datasets/stpere-marina --output marina.mcap
  # The real sonar's thresholded point sets (one PCD per rotation) as beams:
  echofield convert stpere datasets/stpere-marina --keyframes datasets/stpere-marina-sonar \
    --output real.mcap
  # Another calibration (0: use the MTi yaw as the heading):
  echofield convert stpere datasets/stpere-marina --yaw-offset-deg 0 --output raw.mcap

Frames: world x east / y north about the first DGPS fix; vehicle x forward,
y port; yaw counter-clockwise from east (see datasets/stpere-marina/README.md).
The DGPS becomes the ground truth only, never the /position/fix channel: as
the prior of a merge of missions (run with several missions) it would make
the merged error against it meaningless.";

const PING360_EXAMPLES: &str = "\
Examples:
  echofield convert ping360 datasets/msis-real/ping360/Sensor_Log_01__inside_base.bin --output beams.mcap

Beam stamps are seconds since the log began. A damaged log is read as far as it
is valid; what was skipped is printed.";

const MINIKING_EXAMPLES: &str = "\
Examples:
  echofield convert miniking datasets/msis-real/miniking/full_sonar_scan_2015-05-26-11-38-04.bag --output beams.mcap

Only uncompressed bags are read (run `rosbag decompress` on others).";

#[derive(Debug, clap::Args)]
pub struct StPereArgs {
    /// Folder with the `<prefix>_DVL.log`, `_MTI.log`, `_DGPS.log` (and
    /// optional `_SETUP.log`, `_IS_timestamps.log`, `_IS.log`) files.
    pub dir: PathBuf,
    /// A folder of thresholded sonar point sets of the same mission
    /// (`keyFrameTimeStamps.csv` and `pclKeyFrameK.pcd`, one per
    /// rotation): each point goes back to its beam and bin, beams without
    /// points are kept empty. `DIR` must then hold `_SETUP.log` and
    /// `_IS_timestamps.log`, and no `_IS.log`.
    #[arg(long, value_name = "KF_DIR")]
    pub keyframes: Option<PathBuf>,
    /// With --keyframes: which way the head's angle ran with time, since
    /// the point sets do not say (`echofield calibrate` tells).
    #[arg(long, value_enum, default_value_t = Sweep::Increasing, requires = "keyframes")]
    pub sweep: Sweep,
    /// Output MCAP file (written atomically).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Heading calibration in degrees (counter-clockwise positive) that
    /// dead reckoning adds to every MTi yaw, stored as the mission's
    /// `mounting.heading_offset_rad`; the attitude itself is written as
    /// logged. Default: +19.4, fitted against DGPS on the marina mission.
    #[arg(long, default_value_t = MARINA_YAW_OFFSET_RAD.to_degrees(), allow_negative_numbers = true)]
    pub yaw_offset_deg: f64,
}

/// The assumed sweep of point sets (`--sweep`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Sweep {
    /// The angle increases with time.
    Increasing,
    /// The angle decreases with time.
    Decreasing,
}

impl From<Sweep> for SweepTiming {
    fn from(s: Sweep) -> Self {
        match s {
            Sweep::Increasing => SweepTiming::AngleIncreasing,
            Sweep::Decreasing => SweepTiming::AngleDecreasing,
        }
    }
}

#[derive(Debug, clap::Args)]
pub struct SonarArgs {
    /// Input log file.
    pub input: PathBuf,
    /// Output MCAP file (written atomically).
    #[arg(short, long)]
    pub output: PathBuf,
}

pub fn run(args: Args) -> Result<()> {
    match args {
        Args::Stpere(a) => stpere(&a),
        Args::Ping360(a) => sonar(&a, read_ping360),
        Args::Miniking(a) => sonar(&a, read_miniking_bag),
        Args::Ros(a) => ros(&a),
    }
}

fn ros(args: &RosArgs) -> Result<()> {
    super::prepare_output_files([Some(&args.output)])?;
    let mut choice = TopicChoice::default();
    for (role, topic) in &args.topics {
        choice.topics[*role] = Some(topic.clone());
    }
    let (mission, channels) = read_mission_with(&args.input, &choice)
        .with_context(|| format!("cannot read {}", args.input.display()))?;
    super::run::print_channels(&channels);
    write(&args.output, &mission)?;
    println!(
        "wrote {}: {} beams, {} DVL, {} attitude, {} ground-truth poses",
        args.output.display(),
        mission.beams.len(),
        mission.dvl.len(),
        mission.attitude.len(),
        mission.ground_truth.len()
    );
    Ok(())
}

fn stpere(args: &StPereArgs) -> Result<()> {
    super::prepare_output_files([Some(&args.output)])?;
    anyhow::ensure!(
        args.yaw_offset_deg.is_finite(),
        "--yaw-offset-deg must be finite"
    );
    let (mut logs, keyframes) = read_stpere(args)?;
    // The reader puts the marina calibration into the mounting; the
    // option replaces it there (adding it to the attitude as well would
    // correct the heading twice).
    logs.mission.mounting.heading_offset_rad = wrap_angle(args.yaw_offset_deg.to_radians());
    for skip in &logs.skipped {
        tracing::warn!(
            "skipped {}:{}: {:?}",
            skip.path.display(),
            skip.line,
            skip.reason
        );
    }
    write(&args.output, &logs.mission)?;
    let m = &logs.mission;
    let valid = m.dvl.iter().filter(|d| d.valid).count();
    println!(
        "wrote {}: {} beams, {} DVL ({} valid), {} attitude, {} ground-truth poses; \
         heading offset {:+.2} deg in the mounting (the marina's calibration: {:+.1})",
        args.output.display(),
        m.beams.len(),
        m.dvl.len(),
        valid,
        m.attitude.len(),
        m.ground_truth.len(),
        m.mounting.heading_offset_rad.to_degrees(),
        MARINA_YAW_OFFSET_RAD.to_degrees()
    );
    if let Some(kf) = &keyframes {
        print_keyframes(kf);
    }
    if m.beams.is_empty() {
        println!(
            "note: no _IS.log in {}, so the mission has no beams",
            args.dir.display()
        );
    }
    Ok(())
}

/// The St Pere logs of `args.dir`, with the beams rebuilt from the point
/// sets of `args.keyframes` when given (and those rotations).
fn read_stpere(args: &StPereArgs) -> Result<(StPereLogs, Option<KeyframeBeams>)> {
    let Some(kf_dir) = &args.keyframes else {
        let logs = read_stpere_dir(&args.dir)
            .with_context(|| format!("cannot read the St Pere logs in {}", args.dir.display()))?;
        return Ok((logs, None));
    };
    let (logs, kf) = read_stpere_with_keyframes(&args.dir, kf_dir, args.sweep.into())
        .with_context(|| {
            format!(
                "cannot read the St Pere logs in {} with the point sets in {}",
                args.dir.display(),
                kf_dir.display()
            )
        })?;
    Ok((logs, Some(kf)))
}

/// One line on the rotations rebuilt from keyframe point sets.
fn print_keyframes(kf: &KeyframeBeams) {
    let points: usize = kf.rotations.iter().map(|r| r.points).sum();
    println!(
        "  {} rotations ({}-{}) rebuilt from {points} points, stamps assigned with the angle {}",
        kf.rotations.len(),
        kf.rotations.first().map_or(0, |r| r.keyframe),
        kf.rotations.last().map_or(0, |r| r.keyframe),
        match kf.sweep {
            SweepTiming::AngleDecreasing => "decreasing",
            _ => "increasing",
        }
    );
}

fn sonar(
    args: &SonarArgs,
    read: fn(&Path) -> Result<SonarRecording, echofield_datasets::DatasetError>,
) -> Result<()> {
    super::prepare_output_files([Some(&args.output)])?;
    let recording =
        read(&args.input).with_context(|| format!("cannot read {}", args.input.display()))?;
    let s = &recording.stats;
    if let Some(stop) = &s.stopped_early {
        tracing::warn!("{}: stopped early at {stop}", args.input.display());
    }
    write(&args.output, &recording.to_mission())?;
    println!(
        "wrote {}: {} beams from {} ({} records, {} messages; {} bad checksums, {} bad beam \
         messages, {} skipped bytes, {} bytes cut at the end)",
        args.output.display(),
        recording.beams.len(),
        recording.device,
        s.records,
        s.messages,
        s.bad_checksums,
        s.bad_beam_messages,
        s.skipped_bytes,
        s.truncated_tail_bytes
    );
    if let Some(stop) = &s.stopped_early {
        println!("warning: the file is damaged; read up to {stop}");
    }
    for seg in recording.range_segments() {
        println!(
            "  beams {}..{}: {:.2} m range, {} bins of {:.4} m, {:.2} turns swept",
            seg.first_beam,
            seg.first_beam + seg.beam_count,
            seg.range_m(),
            seg.bins,
            seg.bin_size_m,
            seg.swept_rad / std::f64::consts::TAU
        );
    }
    Ok(())
}

fn write(path: &Path, mission: &echofield_frontend::sensors::Mission) -> Result<()> {
    write_mission(path, mission).with_context(|| format!("cannot write {}", path.display()))
}
