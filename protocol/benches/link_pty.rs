//! What a lockstep period costs on the pty transports: one request/answer round trip between a
//! host and a device end in one process (two frames over SLCAN; one ILD cycle), so the loop's
//! achievable lockstep rate over a pty can be read off. Run: `cargo bench -p scanhil-protocol
//! --bench link_pty`.

use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use scanhil_protocol::can::{CanFrame, CanId};
use scanhil_protocol::link::{CanLink, IldLink, LinkUri, PtyPair, Role};

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("a tokio runtime")
}

/// Host on the slave path, device on the master; the device answers the host's open.
async fn slcan_pair() -> (CanLink, CanLink) {
    let pair = PtyPair::open().expect("a pty pair");
    let uri: LinkUri = format!("slcan:{}@1M", pair.slave_path().display())
        .parse()
        .expect("a valid URI");
    let mut device = CanLink::open_pty(pair, None, Role::Device)
        .await
        .expect("device end");
    let host = CanLink::open(&uri, Role::Host);
    tokio::pin!(host);
    let host = loop {
        tokio::select! {
            host = &mut host => break host.expect("host end"),
            _ = device.recv_timeout(Duration::from_secs(1)) => {}
        }
    };
    (host, device)
}

fn slcan_round_trip(c: &mut Criterion) {
    let rt = runtime();
    let (mut host, mut device) = rt.block_on(slcan_pair());
    let command = CanFrame::new(CanId::standard(0x100).expect("id"), &[1; 8]).expect("frame");
    let answer = CanFrame::new(CanId::standard(0x110).expect("id"), &[2; 8]).expect("frame");
    c.bench_function("slcan pty round trip (8-byte frame each way)", |b| {
        b.iter_custom(|iters| {
            rt.block_on(async {
                let started = Instant::now();
                for _ in 0..iters {
                    host.send(&command).await.expect("send");
                    device.recv().await.expect("recv");
                    device.send(&answer).await.expect("send");
                    host.recv().await.expect("recv");
                }
                started.elapsed()
            })
        });
    });
}

fn ild_cycle(c: &mut Criterion) {
    let rt = runtime();
    let (mut host, mut device) = rt.block_on(async {
        let pair = PtyPair::open().expect("a pty pair");
        let uri: LinkUri = format!("ild:{}", pair.slave_path().display())
            .parse()
            .expect("a valid URI");
        let device = IldLink::open_pty(pair, 691_200, Role::Device).expect("device end");
        (IldLink::open(&uri, Role::Host).expect("host end"), device)
    });
    host.set_values_per_cycle(2);
    c.bench_function("ild pty cycle (distance + counter)", |b| {
        b.iter_custom(|iters| {
            rt.block_on(async {
                let started = Instant::now();
                for k in 0..iters {
                    device
                        .send_cycle(&[32_000, (k & 0x3FFFF) as u32])
                        .await
                        .expect("send");
                    host.recv_cycle().await.expect("recv");
                }
                started.elapsed()
            })
        });
    });
}

criterion_group!(benches, slcan_round_trip, ild_cycle);
criterion_main!(benches);
