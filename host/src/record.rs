//! `taxel record`: streams sample frames from the device into a recording (see
//! [`crate::recording`]: a CSV file, a raw byte log and the device's state). Ctrl-C, an
//! unplugged device or the sample limit end it; the files are then renamed into place with
//! everything received. Several devices at once are recorded onto one host timeline by
//! [`crate::multi_record`].

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use wire::{Command, CountersFrame, DeviceFrame, InfoFrame, ReplyPayload};

pub use crate::device_link::parse_hex_u16;
use crate::device_link::{DeviceLink, LinkError};
use crate::device_words::{event_words, info_words};
use crate::recording::{read_device_state, BaselineFollower, RecordedDeviceState, SampleSink};
use crate::stream_accounting::StreamAccounting;

pub use crate::recording::{record_header, sample_cells};
pub use crate::stream_accounting::sequence_gap;

/// Why a recording ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StopReason {
    /// Ctrl-C (or the stop flag was set).
    Interrupted,
    /// The requested number of samples was reached.
    SampleLimit,
    /// The device went away; the message says how.
    Disconnected(String),
}

/// What a recording captured.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordSummary {
    /// Sample frames received (every pad's).
    pub samples: u64,
    /// Sample frames missing from the sequence numbers while streaming, summed over the pads.
    pub sequence_gap_samples: u64,
    /// Where every sample set went (received, lost on the link, dropped by the device).
    pub accounting: StreamAccounting,
    /// Bytes received (all in the raw log).
    pub bytes_received: u64,
    /// Frames that could not be decoded.
    pub frames_rejected: u64,
    /// Why it ended.
    pub stop_reason: StopReason,
}

/// Records from an open link until `stop` is set, `max_samples` are written, or the link
/// fails, with a fresh accounting; see [`record_accounted`].
pub fn record_link<P: Read + Write, S: SampleSink + ?Sized>(
    link: &mut DeviceLink<P>,
    sink: &mut S,
    stop: &AtomicBool,
    max_samples: Option<u64>,
    flush_interval: Duration,
    status: &mut dyn FnMut(&str),
) -> anyhow::Result<RecordSummary> {
    let mut accounting = StreamAccounting::new();
    let stop_reason = record_accounted(
        link,
        sink,
        &mut accounting,
        stop,
        max_samples,
        flush_interval,
        status,
    )?;
    Ok(RecordSummary {
        samples: accounting.received(),
        sequence_gap_samples: accounting.sequence_gap_sets(),
        accounting,
        bytes_received: link.statistics().bytes_received,
        frames_rejected: link.statistics().frames_rejected,
        stop_reason,
    })
}

/// Records from an open link until `stop` is set, `max_samples` rows are written in this call
/// (frames, for a sink that does not count rows), or the link fails. A frame that would close
/// the sample set in progress once the limit is reached is left unread by the sink, so that the
/// last row is that set's. Other frames are reported through `status` in words; counters go to
/// the accounting. The sink and the link's raw log are flushed at least every `flush_interval` and
/// at the end, also when writing fails (one file failing must not cost the other its data).
pub fn record_accounted<P: Read + Write, S: SampleSink + ?Sized>(
    link: &mut DeviceLink<P>,
    sink: &mut S,
    accounting: &mut StreamAccounting,
    stop: &AtomicBool,
    max_samples: Option<u64>,
    flush_interval: Duration,
    status: &mut dyn FnMut(&str),
) -> anyhow::Result<StopReason> {
    let result = record_until_stopped(
        link,
        sink,
        accounting,
        stop,
        max_samples,
        flush_interval,
        status,
    );
    if result.is_err() {
        let _ = sink.flush();
        let _ = link.flush_raw_log();
    }
    result
}

fn record_until_stopped<P: Read + Write, S: SampleSink + ?Sized>(
    link: &mut DeviceLink<P>,
    sink: &mut S,
    accounting: &mut StreamAccounting,
    stop: &AtomicBool,
    max_samples: Option<u64>,
    flush_interval: Duration,
    status: &mut dyn FnMut(&str),
) -> anyhow::Result<StopReason> {
    let mut last_flush = Instant::now();
    let received_before = accounting.received();
    let rows_before = sink.rows();
    let written = |sink: &S, accounting: &StreamAccounting| match (sink.rows(), rows_before) {
        (Some(rows), Some(before)) => rows.saturating_sub(before),
        _ => accounting.received().saturating_sub(received_before),
    };
    let mut baselines = BaselineFollower::default();
    // The device repeats these unsolicited; only changes are worth a line.
    let mut last_info = None;
    let baseline_timeout = Duration::from_millis(1000);
    let stop_reason = loop {
        if stop.load(Ordering::Relaxed) {
            break StopReason::Interrupted;
        }
        if max_samples.is_some_and(|limit| written(sink, accounting) >= limit) {
            break StopReason::SampleLimit;
        }
        match link.next_frame() {
            Ok(Some(DeviceFrame::Sample(sample))) => {
                if max_samples.is_some_and(|limit| {
                    sink.would_close_set(&sample) && written(sink, accounting) + 1 >= limit
                }) {
                    break StopReason::SampleLimit;
                }
                baselines.before_sample(sink, &sample);
                sink.write_sample(&sample).with_context(|| {
                    format!("writing the CSV after {} samples", accounting.received())
                })?;
                accounting.sample(&sample);
            }
            Ok(Some(DeviceFrame::Event(event))) => {
                status(&event_words(&event));
                sink.device_event(&event)?;
                if let Err(error) = baselines.on_event(link, &event, baseline_timeout) {
                    status(&format!(
                        "warning: the device's new baselines could not be read ({}); `convert` will not reproduce the pressures after this point",
                        crate::console::error_message(&error)
                    ));
                }
            }
            Ok(Some(DeviceFrame::Info(info))) => {
                if last_info != Some(info) {
                    status(&format!("device: {}", info_words(&info)));
                    last_info = Some(info);
                }
            }
            Ok(Some(DeviceFrame::Counters(counters))) => accounting.counters(&counters),
            Ok(Some(DeviceFrame::Reply(reply))) => match reply.result {
                Ok(ReplyPayload::Counters(counters)) => accounting.counters(&counters),
                Ok(_) => {}
                Err(code) => status(&format!(
                    "the device refused request {}: {code:?}",
                    reply.request_id
                )),
            },
            Ok(None) => {}
            Err(LinkError::RawLog(error)) => return Err(error).context("writing the raw log"),
            Err(error) => break StopReason::Disconnected(error.to_string()),
        }
        if last_flush.elapsed() >= flush_interval {
            sink.flush()?;
            link.flush_raw_log().context("writing the raw log")?;
            last_flush = Instant::now();
        }
    };
    sink.flush()?;
    link.flush_raw_log().context("writing the raw log")?;
    Ok(stop_reason)
}

/// The start of a recording on an open link: asks who the device is (`announce` gets its Info
/// to say so), then reads its state, every pad's. The stream starts later ([`start_stream`]),
/// once the raw log is in place. Returns the Info, the state and how many stale frames were
/// discarded.
pub fn identify_device<P: Read + Write>(
    link: &mut DeviceLink<P>,
    timeout: Duration,
    announce: &mut dyn FnMut(&InfoFrame),
) -> anyhow::Result<(InfoFrame, RecordedDeviceState, u64)> {
    let (info, stale) = link
        .synchronise(timeout)
        .context("asking the device who it is")?;
    announce(&info);
    let state = read_device_state(link, &info, timeout)?;
    Ok((info, state, stale))
}

/// Starts the stream: an accounting that begins with the `stale` frames discarded and the
/// device's counters now (when it gives them), then StartStreaming.
pub fn start_stream<P: Read + Write>(
    link: &mut DeviceLink<P>,
    stale: u64,
    timeout: Duration,
) -> anyhow::Result<StreamAccounting> {
    let mut accounting = StreamAccounting::new();
    accounting.stale_discarded(stale);
    if let Ok(ReplyPayload::Counters(counters)) = link.request(Command::ReadCounters, timeout) {
        accounting.counters(&counters);
    }
    link.request(Command::StartStreaming, timeout)
        .context("starting the stream")?;
    Ok(accounting)
}

/// The end of a recording: unless the device went away, StopStreaming and the device's
/// counters, which go to the accounting and are returned for the user.
pub fn stop_stream<P: Read + Write>(
    link: &mut DeviceLink<P>,
    accounting: &mut StreamAccounting,
    stop_reason: &StopReason,
) -> Option<CountersFrame> {
    if matches!(stop_reason, StopReason::Disconnected(_)) {
        return None;
    }
    // Best effort: the recording is complete whether or not the device hears this.
    let _ = link.send(Command::StopStreaming);
    match link.request(Command::ReadCounters, Duration::from_millis(500)) {
        Ok(ReplyPayload::Counters(counters)) => {
            accounting.counters(&counters);
            Some(counters)
        }
        _ => None,
    }
}

/// Why a recording ended, for the closing line.
pub fn stop_words(stop_reason: &StopReason) -> String {
    match stop_reason {
        StopReason::Interrupted => "stopped by Ctrl-C".to_owned(),
        StopReason::SampleLimit => "sample limit reached".to_owned(),
        StopReason::Disconnected(message) => format!("device disconnected: {message}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_ids_parse_with_or_without_prefix() {
        assert_eq!(parse_hex_u16("0x1209"), Ok(0x1209));
        assert_eq!(parse_hex_u16("1209"), Ok(0x1209));
        assert!(parse_hex_u16("0xZZ").is_err());
    }
}
