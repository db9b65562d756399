//! Where the emulated sensor's samples go: the ILD 2300's own RS422 byte stream on a serial
//! line or pty (one output cycle per sample: the distance value, then the 18-bit measured-value
//! counter, as a sensor configured with `OUTADD_RS422 COUNTER` sends them), or Distance frames
//! on the mirror's CAN link.
//!
//! The summary line declares the sensor's clock (measuring rate, and the loop time its counter
//! 0 stands for) so the host can place each distance in time; for a real sensor the host
//! estimates it instead.

use scanhil_protocol::link::ild::IldLink;
use scanhil_protocol::link::role::Role;
use scanhil_protocol::link::{CanLink, LinkUri, PtyPair};

use crate::scene::Scene;
use crate::sensor::IldSample;
use scanhil_protocol::message::{Distance, Message, U24_MAX};

/// The sensor's output.
#[derive(Debug)]
pub enum SensorPort {
    /// The scene has no sensor, or no sensor link was asked for: samples are dropped.
    Off,
    /// The ILD RS422 stream (device end).
    Ild(Box<IldLink>, SensorClockTrack),
    /// Distance frames on the mirror's CAN link.
    Can(SensorClockTrack),
}

/// What the sensor has sent and when its counter started.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct SensorClockTrack {
    /// Samples sent.
    pub samples: u64,
    /// The loop time counter value 0 stands for, s (`None` before the first sample).
    pub counter_zero_s: Option<f64>,
    /// The sensor's measuring rate, Hz.
    pub measuring_rate_hz: f64,
}

impl SensorPort {
    /// Opens the sensor's link: `None` (no sensor served), `ild:pty` (a new pty pair),
    /// `ild:PATH[@BAUD]`, or `fsm` (Distance frames on the mirror's link). Returns the port
    /// and the link's name for the ready line.
    ///
    /// # Errors
    /// A link that does not open, a CAN URI given for the sensor, or a sensor link for a
    /// scene without a sensor.
    pub fn open(uri: Option<&str>, scene: &Scene) -> anyhow::Result<(SensorPort, String)> {
        let Some(uri) = uri else {
            return Ok((SensorPort::Off, String::new()));
        };
        if !scene.has(crate::scene::Part::Sensor) {
            anyhow::bail!(
                "--sensor {uri}: scene `{}` has no `sensor` part to serve",
                scene.name
            );
        }
        let clock = SensorClockTrack {
            samples: 0,
            counter_zero_s: None,
            measuring_rate_hz: scene.sensor.unwrap_or_default().measuring_rate_hz,
        };
        if uri == "fsm" {
            return Ok((SensorPort::Can(clock), "fsm".into()));
        }
        if uri == "ild:pty" {
            let link = IldLink::open_pty(PtyPair::open()?, Role::Device)?;
            let name = link.name().to_owned();
            return Ok((SensorPort::Ild(Box::new(link), clock), name));
        }
        match uri.parse::<LinkUri>()? {
            parsed @ LinkUri::Ild { .. } => {
                let link = IldLink::open(&parsed, Role::Device)?;
                let name = link.name().to_owned();
                Ok((SensorPort::Ild(Box::new(link), clock), name))
            }
            other => anyhow::bail!(
                "--sensor {other}: the sensor speaks the ILD stream (`ild:PATH`) or Distance \
                 frames on the mirror's link (`fsm`)"
            ),
        }
    }

    /// Sends the samples of one period, in order.
    ///
    /// # Errors
    /// Link errors.
    pub async fn emit(&mut self, samples: &[IldSample], fsm: &mut CanLink) -> anyhow::Result<()> {
        match self {
            SensorPort::Off => {}
            SensorPort::Ild(link, clock) => {
                for sample in samples {
                    clock.count(sample);
                    link.send_cycle(&[sample.value.raw(), sample.counter])
                        .await?;
                }
            }
            SensorPort::Can(clock) => {
                for sample in samples {
                    clock.count(sample);
                    let counter = sample.counter;
                    let sensor_time_us =
                        ((sample.t_s * 1e6).round() as u64 & u64::from(U24_MAX)) as u32;
                    let distance = Distance {
                        value: sample.value,
                        counter,
                        sensor_time_us,
                    };
                    fsm.send(&Message::Distance(distance).encode()?).await?;
                }
            }
        }
        Ok(())
    }

    /// What the sensor sent, for the summary line.
    #[must_use]
    pub fn summary(&self) -> Option<SensorClockTrack> {
        match self {
            SensorPort::Off => None,
            SensorPort::Ild(_, clock) | SensorPort::Can(clock) => Some(*clock),
        }
    }
}

impl SensorClockTrack {
    /// Counts one sample sent; the first one fixes the loop time of counter 0.
    pub fn count(&mut self, sample: &IldSample) {
        if self.counter_zero_s.is_none() {
            self.counter_zero_s =
                Some(sample.t_s - f64::from(sample.counter) / self.measuring_rate_hz);
        }
        self.samples += 1;
    }
}
