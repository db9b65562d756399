//! How a serve run winds down, in lockstep and in real time alike: the node's last frames
//! ([`send_last_frames`]), the linger that lets the host read them ([`linger`]), and the end
//! on a link error ([`end_on_link_error`]).
//!
//! The host's hang-up or its closing of the SLCAN channel is the end of its session: the run
//! finishes. Any other link error (SocketCAN bus-off, an OS error on a line, a peer breaking
//! the link's protocol, the sensor's line failing) ends the run as the watchdog does: the
//! node drops its coil currents to zero ([`MirrorNode::on_link_failure`]), its fault frame and
//! Status(fault) are attempted where the link can still send (each waits at most
//! [`LAST_FRAME_ALLOWANCE`], so a bus-off controller or
//! a dead line never holds the emulator), and the summary says why (`ended_by: bus_off` or
//! `link_failed`, the error's text in `error`; exit 3).

use std::time::Duration;

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::link::LinkError;
use scanhil_protocol::message::MessageError;

use super::lockstep_node::last_frames;
use super::mirror_node::MirrorNode;
use super::{LoopReport, RunEnd, ServeLinks, ServeOutcome};

/// Ends the run on `error`. A link error (anywhere in its chain) gives the report: the host's
/// hang-up or closing of the channel finishes the run; a failure zeroes the node's coils,
/// attempts its last frames (and, on SLCAN, lingers so the host can read them) and reports
/// the failure with the error's text. The report's `timing` is null.
///
/// # Errors
/// `error` itself when it is no link error (a plant error, a frame that cannot be encoded).
pub async fn end_on_link_error(
    node: &mut MirrorNode,
    links: &mut ServeLinks,
    error: anyhow::Error,
) -> anyhow::Result<LoopReport> {
    end_on_link_error_with(links, error, || {
        let fault = node.on_link_failure();
        last_frames(node, fault)
    })
    .await
}

/// Ends the run on `error` as [`end_on_link_error`] does, for any node: on a failure,
/// `on_failure` zeroes the node's coils and gives its last frames (a replayed session's are
/// [`super::replay_node::ReplayNode::on_link_failure`]).
///
/// # Errors
/// As [`end_on_link_error`].
pub async fn end_on_link_error_with(
    links: &mut ServeLinks,
    error: anyhow::Error,
    on_failure: impl FnOnce() -> Result<[CanFrame; 2], MessageError>,
) -> anyhow::Result<LoopReport> {
    let Some(link_error) = error.downcast_ref::<LinkError>() else {
        return Err(error);
    };
    let ended_by = RunEnd::of_link_error(link_error);
    if ended_by.outcome() == ServeOutcome::Finished {
        return Ok(LoopReport {
            outcome: ended_by.outcome(),
            ended_by,
            timing: serde_json::Value::Null,
            error: None,
        });
    }
    let reason = scanhil_protocol::error_text::chain_text(&*error);
    let frames = on_failure()?;
    let lingers = links.fsm.is_slcan();
    let wound_down = wind_down(links, &frames, lingers).await;
    Ok(LoopReport {
        outcome: ended_by.outcome(),
        ended_by,
        timing: serde_json::Value::Null,
        error: Some(with_wind_down(reason, wound_down)),
    })
}

/// Sends the node's last frames ([`send_last_frames`]) and, with `lingers`, keeps the link
/// open for the host to read them ([`linger`]). Never fails: the run is ending for a reason
/// already known; a link error on the way ends the wind-down and is returned as text.
pub async fn wind_down(
    links: &mut ServeLinks,
    frames: &[CanFrame],
    lingers: bool,
) -> Result<(), String> {
    send_last_frames(links, frames)
        .await
        .map_err(|error| format!("the node's last frames were not sent: {error}"))?;
    if lingers {
        linger(links)
            .await
            .map_err(|error| format!("the link failed after the node's last frames: {error}"))?;
    }
    Ok(())
}

/// The reason a run ended, followed by what went wrong while winding down, if anything.
#[must_use]
pub fn with_wind_down(reason: String, wound_down: Result<(), String>) -> String {
    match wound_down {
        Ok(()) => reason,
        Err(trouble) => format!("{reason}; {trouble}"),
    }
}

/// How long the node keeps the link open after its last frames, so the host can read them
/// (closing a pty drops what the other end has not read yet).
pub const LINGER: Duration = Duration::from_secs(2);

/// How long each of the node's last frames may wait for a full line before it is left queued.
pub const LAST_FRAME_ALLOWANCE: Duration = Duration::from_millis(2);

/// Sends the node's last frames (its fault and status) without letting a full line hold it:
/// a frame the line does not take within [`LAST_FRAME_ALLOWANCE`] stays queued in the link
/// and goes out while [`linger`] reads, if the host reads at all. A host that has hung up
/// is no error here.
///
/// # Errors
/// A link error other than the host's hang-up.
pub async fn send_last_frames(links: &mut ServeLinks, frames: &[CanFrame]) -> anyhow::Result<()> {
    for frame in frames {
        match tokio::time::timeout(LAST_FRAME_ALLOWANCE, links.fsm.send(frame)).await {
            Err(_) | Ok(Ok(())) => {}
            Ok(Err(error)) if RunEnd::from_link_error(&error).is_some() => return Ok(()),
            Ok(Err(error)) => return Err(error.into()),
        }
    }
    Ok(())
}

/// Keeps the link open, ignoring what arrives, until the host hangs up, closes the channel, or
/// [`LINGER`] passes. It reads without ever waiting on a write: when the host is itself blocked
/// writing into a full line (it was frozen while the node kept sending), draining its frames
/// unblocks it, and the node's queued frames go out as the host reads (a blocking write here
/// would deadlock both ends).
///
/// # Errors
/// A link error other than the hang-up.
pub async fn linger(links: &mut ServeLinks) -> anyhow::Result<()> {
    let deadline = tokio::time::Instant::now() + LINGER;
    while tokio::time::Instant::now() < deadline {
        match links.fsm.try_recv() {
            Ok(Some(_)) => {}
            Ok(None) => tokio::time::sleep(Duration::from_millis(1)).await,
            Err(error) if RunEnd::from_link_error(&error).is_some() => return Ok(()),
            Err(error) => return Err(error.into()),
        }
        if !links.fsm.channel_open() {
            return Ok(());
        }
    }
    Ok(())
}
