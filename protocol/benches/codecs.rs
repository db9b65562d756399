//! Throughput of the wire codecs: how many frames / values per second each decoder and
//! encoder handles (a 20 kHz loop needs at most 40 000 frames/s each way).
//! `cargo bench -p scanhil-protocol --bench codecs`.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use scanhil_protocol::candump::{self, LogEntry, Timestamp};
use scanhil_protocol::ild::{IldDecoder, encode_cycle};
use scanhil_protocol::message::{AngleReading, CoilCommand, Message};
use scanhil_protocol::slcan::{self, SlcanDecoder};

/// Frames (or ILD values) per benchmark batch.
const BATCH: u32 = 1_000;

fn loop_messages() -> Vec<Message> {
    (0..BATCH)
        .map(|k| {
            let seq = k as u16;
            let k = k as i32;
            if k % 2 == 0 {
                Message::CoilCommand(CoilCommand {
                    seq,
                    current_a_ua: k * 997 - 500_000,
                    current_b_ua: -k * 311,
                })
            } else {
                Message::AngleReading(AngleReading {
                    seq,
                    alpha_urad: k * 13 - 6_000,
                    beta_urad: 4_000 - k * 7,
                })
            }
        })
        .collect()
}

fn codecs(c: &mut Criterion) {
    let messages = loop_messages();
    let frames: Vec<_> = messages.iter().map(|m| m.encode().unwrap()).collect();
    let mut group = c.benchmark_group("codecs");
    group.throughput(Throughput::Elements(u64::from(BATCH)));

    group.bench_function("message_encode", |b| {
        b.iter(|| {
            for m in &messages {
                black_box(m.encode().unwrap());
            }
        })
    });
    group.bench_function("message_decode", |b| {
        b.iter(|| {
            for f in &frames {
                black_box(Message::decode(black_box(f)).unwrap());
            }
        })
    });

    let slcan_text: String = frames.iter().map(slcan::encode_frame).collect();
    group.bench_function("slcan_encode", |b| {
        b.iter(|| {
            for f in &frames {
                black_box(slcan::encode_frame(f));
            }
        })
    });
    group.bench_function("slcan_decode", |b| {
        b.iter(|| black_box(SlcanDecoder::new().push(slcan_text.as_bytes())))
    });

    let log: String = frames
        .iter()
        .zip(0u32..)
        .map(|(&frame, i)| {
            let entry = LogEntry {
                timestamp: Timestamp {
                    secs: 1_700_000_000,
                    nanos: i * 50_000,
                },
                interface: "vcan0".to_owned(),
                frame,
                len8_dlc: None,
                direction: None,
            };
            format!("{entry}\n")
        })
        .collect();
    group.bench_function("candump_parse", |b| {
        b.iter(|| {
            for entry in candump::parse_log(&log) {
                black_box(entry.unwrap());
            }
        })
    });

    let ild_bytes: Vec<u8> = (0..BATCH)
        .flat_map(|k| encode_cycle(&[k * 61 % 65_000]))
        .collect();
    group.bench_function("ild_decode", |b| {
        b.iter(|| black_box(IldDecoder::new().push(&ild_bytes)))
    });
    group.finish();
}

criterion_group!(benches, codecs);
criterion_main!(benches);
