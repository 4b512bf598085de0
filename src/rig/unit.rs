//! One unit of a rig: what it is made of (a three-axis IMU sharing its grid's evaluation, one
//! with a producer of its own, or a skew-redundant unit), and what it tells about itself.

use super::skew::ChannelErrors;
use super::{Failure, FailureSet, Placement, SinkAddr, SkewLayout};
use crate::aiding::mag_samples::MagHold;
use crate::engine::{Encoding, Grid, Producer};
use crate::errors::ErrorChain;
use crate::errors::temperature::TemperatureProfile;
use crate::errors::vibration::Vibration;
use crate::math::Vec3;
use crate::output::Format;
use crate::protocol::{EncoderState, Plan};
use crate::record::COLUMNS;

/// What a unit is made of.
pub(crate) enum Body {
    /// A three-axis IMU: its template's error chain (without mounting or lever arm, which
    /// the placement applies) and its output encoding.
    Triad {
        chain: Option<Box<ErrorChain>>,
        encoding: Box<Encoding>,
    },
    /// A three-axis IMU whose template has an output filter or timing errors (or under the
    /// scene file's `[timing]`): the single IMU's producer of its own (the template's chain or
    /// filtered chain with the unit's mounting, lever arm, temperature and the body's
    /// vibration, its sampling clock, its truth placed at the unit), which evaluates the
    /// motion itself at the instants it needs; the failures act after it, then the encoding.
    Produced {
        producer: Box<Producer>,
        encoding: Box<Encoding>,
        /// The end of the last triggered sample's interval (s after t₀): the next one's start.
        last_tov: f64,
    },
    /// A skew-redundant unit: its sensors and their error terms; CSV output, or the frames of
    /// an N-channel protocol (its compiled plan and encoder state).
    Skew {
        layout: SkewLayout,
        errors: Vec<ChannelErrors>,
        frames: Option<Box<(Plan, EncoderState)>>,
        /// The body's vibration (body axes), added to the error-free signal at each sensor.
        vibration: Option<Box<Vibration>>,
    },
}

/// One unit of a rig, ready to produce.
pub struct Unit {
    pub(crate) name: String,
    /// The template's name, or the skew unit's sensors in words.
    pub(crate) model: String,
    pub(crate) grid: Grid,
    pub(crate) place: Placement,
    pub(crate) body: Body,
    pub(crate) failures: FailureSet,
    pub(crate) seed: u64,
    pub(crate) path: Option<std::path::PathBuf>,
    pub(crate) sinks: Vec<(SinkAddr, Option<String>)>,
    /// The sensor temperature over the run: the template's thermal terms follow it (in the
    /// chain) and frames with a temperature field carry it.
    pub(crate) temperature: Option<TemperatureProfile>,
    /// The magnetometer whose latest sample (in the unit's axes) the frames carry.
    pub(crate) mag: Option<Box<MagHold>>,
    /// Status flags every record carries from now on (e.g. stale input).
    pub(crate) flags: u8,
    /// The unit samples at external trigger edges ([`RigStream::triggered`]).
    pub(crate) triggered: bool,
    /// Further protocols the same records are encoded in ([`Unit::add_protocol`]).
    pub(crate) extra: Vec<Encoding>,
}

impl Unit {
    /// The unit's name (unique in its rig).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// What the unit is: `template NAME`, or `skew-redundant, G gyros and A accelerometers`.
    pub fn model_name(&self) -> &str {
        &self.model
    }

    /// The unit's time grid.
    pub fn grid(&self) -> Grid {
        self.grid
    }

    /// The unit's placement on the body.
    pub fn placement(&self) -> &Placement {
        &self.place
    }

    /// The unit's seed (its error terms' and failures' random streams).
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The output path the scene file gives, if any.
    pub fn path(&self) -> Option<&std::path::Path> {
        self.path.as_deref()
    }

    /// Where `imu-emu run` streams the unit (the scene file's `sink`), each with its protocol
    /// when it is not the unit's own.
    pub fn sinks(&self) -> &[(SinkAddr, Option<String>)] {
        &self.sinks
    }

    /// The compiled frame of a unit that speaks a protocol.
    pub fn plan(&self) -> Option<&crate::protocol::Plan> {
        match self.encoding()? {
            Encoding::Frames { plan, .. } => Some(plan),
            Encoding::Records(_) => None,
        }
    }

    /// A three-axis unit's output encoding.
    pub(super) fn encoding(&self) -> Option<&Encoding> {
        match &self.body {
            Body::Triad { encoding, .. } | Body::Produced { encoding, .. } => Some(encoding),
            Body::Skew { .. } => None,
        }
    }

    /// Whether the unit runs a producer of its own (an output filter, timing errors) instead
    /// of sharing its grid's evaluation of the motion.
    pub fn has_own_producer(&self) -> bool {
        matches!(self.body, Body::Produced { .. })
    }

    /// Whether the unit runs its template's output filter.
    pub fn has_output_filter(&self) -> bool {
        matches!(&self.body, Body::Produced { producer, .. } if producer.is_filtered())
    }

    /// Whether the unit's records carry their own times of validity and emission (timing
    /// errors, an output filter's delay, a trigger): its truth then has the `tov`,
    /// `tov_accel` and `emit` columns, as the single IMU's has.
    pub fn is_timed(&self) -> bool {
        self.triggered
            || matches!(&self.body, Body::Produced { producer, .. } if producer.is_timed())
    }

    /// The skew-redundant layout, if the unit is one.
    pub fn skew(&self) -> Option<&SkewLayout> {
        match &self.body {
            Body::Skew { layout, .. } => Some(layout),
            Body::Triad { .. } | Body::Produced { .. } => None,
        }
    }

    /// The failures, their random choices made.
    pub fn failures(&self) -> &[Failure] {
        self.failures.failures()
    }

    /// The resolved failure schedule as CSV: a header, then one line per failure.
    pub fn failure_csv(&self) -> String {
        let names = self.channel_names();
        let mut text = String::from("kind,sensor,channel,start_s,end_s,magnitude\n");
        for x in self.failures() {
            text += &format!(
                "{},{},{},{},{},{}\n",
                x.kind.name(),
                names[x.channel],
                x.channel,
                x.start_s,
                x.end_s,
                x.magnitude
            );
        }
        text
    }

    /// The channel names failures refer to: `gyro_x` … `accel_z`, or `gyro_0` … `accel_N`.
    pub fn channel_names(&self) -> Vec<String> {
        match &self.body {
            Body::Triad { .. } | Body::Produced { .. } => {
                COLUMNS[1..7].iter().map(|s| s.to_string()).collect()
            }
            Body::Skew { layout, .. } => layout.channel_names(),
        }
    }

    /// File extension of the main output: `csv`, or `bin` for binary records and frames.
    pub fn extension(&self) -> &'static str {
        match &self.body {
            Body::Triad { encoding, .. } | Body::Produced { encoding, .. } => match **encoding {
                Encoding::Records(Format::Csv) => "csv",
                _ => "bin",
            },
            Body::Skew { frames, .. } => match frames {
                Some(_) => "bin",
                None => "csv",
            },
        }
    }

    /// Whether this unit needs the rotation terms (a lever arm, offset accelerometers).
    pub(super) fn needs_rotation_terms(&self) -> bool {
        self.place.lever_b != Vec3::zeros()
            || match &self.body {
                Body::Triad { chain, .. } => {
                    chain.as_ref().is_some_and(|c| c.needs_rotation_terms())
                }
                Body::Skew { layout, .. } => layout.has_offsets(),
                Body::Produced { .. } => false,
            }
    }

    /// The header of the main output (CSV only) and of the truth file.
    pub(crate) fn headers(&self) -> (String, String) {
        let names = match &self.body {
            Body::Triad { .. } | Body::Produced { .. } => {
                COLUMNS[1..].iter().map(|s| s.to_string()).collect()
            }
            Body::Skew { layout, .. } => {
                let ch = layout.channel_names();
                let inc = |c: &String| c.replace("gyro_", "dtheta_").replace("accel_", "dv_");
                let mut v = ch.clone();
                v.extend(ch.iter().map(inc));
                v
            }
        };
        let main = format!("t,{}\n", names.join(","));
        let times = if self.is_timed() {
            ",tov,tov_accel,emit"
        } else {
            ""
        };
        let truth = format!("t,{}{times},failed\n", names.join(","));
        let main = match &self.body {
            Body::Triad { encoding, .. } | Body::Produced { encoding, .. }
                if !matches!(**encoding, Encoding::Records(Format::Csv)) =>
            {
                String::new()
            }
            Body::Skew {
                frames: Some(_), ..
            } => String::new(),
            _ => main,
        };
        (main, truth)
    }
}
