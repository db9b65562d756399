//! The lockstep loop over a real link, controller side: the transport shell around
//! [`HostLoop`], which decides what goes out each period and what the frames that come back
//! mean. This loop sends its frames (stamping the capture with their loop time), waits for
//! frames within the watchdog's wall-clock allowance while the sensor's stream is read beside
//! it, and reports a link that failed or stayed silent.

use scanhil_protocol::can::CanFrame;

use super::host_loop::{Heard, HostAction, HostLoop, LoopRecord};
use super::interrupt::Interrupt;
use super::loop_error::LoopError;
use super::mirror_link::MirrorLink;
use super::progress::Progress;
use super::sensor_link::SensorLink;

/// Runs `host`'s lockstep periods over `mirror`, then ends the run with the node. A link
/// error or a stopping signal stops the loop (after commanding zero where the link still
/// allows it) and is returned inside the record, so what was recorded stays. The inbox `host`
/// files frames into goes back to `mirror` at the end. With `repeats_steps` (the host loop
/// built [`HostLoop::with_tries_per_reading`] the watchdog's periods), each answer allowance
/// without a reading sends the period's Step again, until the watchdog's allowance is used up.
pub async fn run(
    repeats_steps: bool,
    mirror: &mut MirrorLink,
    sensor: &mut SensorLink,
    mut host: HostLoop<'_>,
    progress: &Progress,
    interrupt: &mut Interrupt,
) -> LoopRecord {
    let allowance = mirror.total_allowance();
    // With Step repeats armed, each try waits one answer allowance; otherwise the one try
    // waits the watchdog's whole allowance.
    let try_allowance = if repeats_steps {
        mirror.answer_allowance()
    } else {
        allowance
    };
    let mut sent_at = tokio::time::Instant::now();
    let mut periods_started = 0;
    loop {
        let received: Result<CanFrame, LoopError> = match host.next_action() {
            HostAction::Done => break,
            HostAction::Send(frames) => {
                let period = host.record().periods_done;
                if period == periods_started {
                    // The sensor's samples (on its line or on CAN) bound its clock by the
                    // period they arrive in.
                    let now = tokio::time::Instant::now();
                    sensor.period_started(now);
                    host.inbox_mut().distances_mut().period_started(now);
                    periods_started += 1;
                }
                if let Err(error) = mirror
                    .send_within(
                        period,
                        &frames,
                        tokio::time::Instant::now() + allowance,
                        interrupt,
                    )
                    .await
                {
                    host.on_error(error);
                }
                // Each wait's allowance starts when its frames went out.
                sent_at = tokio::time::Instant::now();
                continue;
            }
            HostAction::SendStop(frames) => {
                let period = host.record().periods_done;
                // The stop is one more exchange on the loop's axis: the sensor's last cycles,
                // which arrive after the last period, come with the node's answer to it.
                let now = tokio::time::Instant::now();
                sensor.period_started(now);
                host.inbox_mut().distances_mut().period_started(now);
                if let Err(error) = mirror.send_stop(period, &frames).await {
                    host.on_error(error);
                }
                sent_at = tokio::time::Instant::now();
                continue;
            }
            HostAction::AwaitReading { period, t_s } => {
                let deadline = sent_at + try_allowance;
                let received = tokio::select! {
                    frame = tokio::time::timeout_at(deadline, mirror.recv_at(t_s)) => Some(frame),
                    error = sensor.pump() => {
                        host.on_error(error);
                        None
                    }
                    signal = interrupt.recv() => {
                        host.on_error(LoopError::Interrupted { signal });
                        None
                    }
                };
                match received {
                    None => continue,
                    Some(Err(_elapsed)) => match host.on_silence() {
                        Some(step) => {
                            let deadline = tokio::time::Instant::now() + allowance;
                            if let Err(error) = mirror
                                .send_within(period, &[step], deadline, interrupt)
                                .await
                            {
                                host.on_error(error);
                            }
                            sent_at = tokio::time::Instant::now();
                            continue;
                        }
                        None => Err(mirror.timeout(period, allowance)),
                    },
                    Some(Ok(frame)) => frame.map_err(LoopError::from),
                }
            }
            HostAction::AwaitNodeReady { t_s } => {
                // The sensor's line is read here too: a lockstep node writes every cycle, and
                // one waiting for room on an unread line could not take the end of the run.
                let deadline = sent_at + allowance;
                tokio::select! {
                    frame = tokio::time::timeout_at(deadline, mirror.recv_at(t_s)) => match frame {
                        Err(_elapsed) => Err(mirror.timeout(host.record().periods_done, allowance)),
                        Ok(frame) => frame.map_err(LoopError::from),
                    },
                    error = sensor.pump() => Err(error),
                }
            }
        };
        match received {
            Ok(frame) => {
                if let Heard::Reading(k) = host.on_frame(frame, tokio::time::Instant::now())
                    && k % 256 == 0
                {
                    progress.set(k);
                }
            }
            Err(error) => host.on_error(error),
        }
    }
    let (record, inbox) = host.finish();
    mirror.restore_inbox(inbox);
    progress.set(record.periods_done);
    record
}
