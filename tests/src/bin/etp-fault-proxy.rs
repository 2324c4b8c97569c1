//! `etp-fault-proxy --listen ADDR --to ADDR [--seed S]`: a TCP proxy that
//! plays a bad network between a sensor host and the agent host in the
//! runtime tests (the test machines' kernel has no `netem`).
//!
//! It forwards every accepted connection to `--to`, and takes commands on
//! stdin, one per line, applied at once to every connection (current and
//! later):
//!
//! * `latency MS JITTER_MS` — each chunk is delivered MS ± JITTER_MS
//!   (uniform) after it was read, never before an earlier chunk of its
//!   direction;
//! * `rate BYTES_PER_S` — each direction is paced to that rate (0: none);
//! * `stall SECS up|down|both` — stop reading and forwarding in that
//!   direction for SECS (up: towards `--to`);
//! * `reset` — every open connection is reset (RST to both ends);
//! * `blackhole` — nothing is forwarded any more, in either direction, on any
//!   connection (they stay open);
//! * `heal` — no latency, no rate limit, no stall, no blackhole.
//!
//! It prints `listening` once bound and one line per command applied
//! (`ok <command>`) on stdout, so a test can order its faults by it.

use rand::{RngExt, SeedableRng};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::{TcpListener, TcpStream};
use tokio::time::Instant;

/// The network as the commands set it.
#[derive(Debug, Clone, Default)]
struct Net {
    latency: Duration,
    jitter: Duration,
    /// Bytes per second; 0: unlimited.
    rate: u64,
    /// Per direction (0: up, 1: down), stalled until then.
    stalled_until: [Option<Instant>; 2],
    blackhole: bool,
    /// Bumped by `reset`: a connection whose generation is older resets.
    generation: u64,
}

type Shared = Arc<Mutex<Net>>;

fn net(shared: &Shared) -> Net {
    shared.lock().map(|n| n.clone()).unwrap_or_default()
}

fn usage() -> ! {
    eprintln!("usage: etp-fault-proxy --listen ADDR --to ADDR [--seed S]");
    std::process::exit(2)
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    let mut args = std::env::args().skip(1);
    let (mut listen, mut to, mut seed) = (None, None, 1u64);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--listen" => listen = args.next(),
            "--to" => to = args.next(),
            "--seed" => {
                seed = args
                    .next()
                    .and_then(|s| s.parse().ok())
                    .unwrap_or_else(|| usage())
            }
            _ => usage(),
        }
    }
    let (Some(listen), Some(to)) = (listen, to) else {
        usage()
    };
    let listener = match TcpListener::bind(&listen).await {
        Ok(l) => l,
        Err(e) => {
            eprintln!("etp-fault-proxy: binding {listen}: {e}");
            std::process::exit(1)
        }
    };
    let shared = Shared::default();
    println!("listening");
    tokio::spawn(commands(shared.clone()));
    let mut conn = 0u64;
    loop {
        let Ok((client, _)) = listener.accept().await else {
            continue;
        };
        conn += 1;
        let (shared, to) = (shared.clone(), to.clone());
        tokio::spawn(async move {
            let Ok(server) = TcpStream::connect(&to).await else {
                return;
            };
            forward(client, server, shared, seed.wrapping_add(conn)).await;
        });
    }
}

/// Apply the commands of stdin until it closes (then exit: the test is gone).
async fn commands(shared: Shared) {
    let mut lines = BufReader::new(tokio::io::stdin()).lines();
    while let Ok(Some(line)) = lines.next_line().await {
        let w: Vec<&str> = line.split_whitespace().collect();
        let ms = |s: &str| s.parse::<u64>().ok().map(Duration::from_millis);
        let applied = shared.lock().ok().and_then(|mut n| {
            match w.as_slice() {
                ["latency", l, j] => {
                    n.latency = ms(l)?;
                    n.jitter = ms(j)?;
                }
                ["rate", r] => n.rate = r.parse().ok()?,
                ["stall", secs, dir] => {
                    let until = Instant::now() + Duration::from_secs_f64(secs.parse().ok()?);
                    let dirs: &[usize] = match *dir {
                        "up" => &[0],
                        "down" => &[1],
                        "both" => &[0, 1],
                        _ => return None,
                    };
                    for &d in dirs {
                        n.stalled_until[d] = Some(until);
                    }
                }
                ["reset"] => n.generation += 1,
                ["blackhole"] => n.blackhole = true,
                ["heal"] => {
                    let generation = n.generation;
                    *n = Net {
                        generation,
                        ..Net::default()
                    };
                }
                _ => return None,
            }
            Some(())
        });
        match applied {
            Some(()) => println!("ok {line}"),
            None => println!("error: not a command: {line}"),
        }
    }
    std::process::exit(0)
}

/// Carry one connection both ways until either end closes or a reset.
async fn forward(client: TcpStream, server: TcpStream, shared: Shared, seed: u64) {
    // SO_LINGER 0 on both sockets: a connection dropped on a reset closes
    // with RST to both ends (an end's own close is still passed on as FIN
    // first, by `shutdown`).
    for s in [&client, &server] {
        let _ = s.set_nodelay(true);
        #[allow(deprecated)]
        let _ = s.set_linger(Some(Duration::ZERO));
    }
    let (cr, cw) = client.into_split();
    let (sr, sw) = server.into_split();
    let mut tasks = tokio::task::JoinSet::new();
    for (dir, from, to, seed) in [(0, cr, sw, seed), (1, sr, cw, seed ^ 0x9E37)] {
        let (tx, rx) = tokio::sync::mpsc::unbounded_channel();
        tasks.spawn(read_side(from, tx, dir, shared.clone(), seed));
        tasks.spawn(write_side(rx, to, dir, shared.clone()));
    }
    // Either direction over (an end closed, or a reset): the connection is.
    let _ = tasks.join_next().await;
    tasks.abort_all();
    while tasks.join_next().await.is_some() {}
}

/// One direction's reading: each chunk stamped with when it is due (read
/// time + latency ± jitter, never before the previous chunk). Stops
/// reading while stalled, so the sender's TCP window fills as on a stalled
/// network.
async fn read_side(
    mut from: tokio::net::tcp::OwnedReadHalf,
    tx: tokio::sync::mpsc::UnboundedSender<(Instant, Vec<u8>)>,
    dir: usize,
    shared: Shared,
    seed: u64,
) {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut buf = vec![0u8; 16 * 1024];
    let mut last = Instant::now();
    loop {
        wait_while_stopped(&shared, dir).await;
        let n = match from.read(&mut buf).await {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        let net = net(&shared);
        let jitter = Duration::from_micros(rng.random_range(0..=2 * net.jitter.as_micros() as u64));
        let read_at = Instant::now();
        let due = (read_at + net.latency + jitter)
            .checked_sub(net.jitter)
            .unwrap_or(read_at)
            .max(last);
        last = due;
        if tx.send((due, buf[..n].to_vec())).is_err() {
            return;
        }
    }
}

/// One direction's writing: each chunk at its due time, paced to the rate,
/// held while stalled or blackholed; a reset ends it (the connection is then
/// dropped, with RST).
async fn write_side(
    mut rx: tokio::sync::mpsc::UnboundedReceiver<(Instant, Vec<u8>)>,
    mut to: tokio::net::tcp::OwnedWriteHalf,
    dir: usize,
    shared: Shared,
) {
    let generation = net(&shared).generation;
    let mut free_at = Instant::now();
    loop {
        let next = tokio::select! {
            m = rx.recv() => m,
            () = tokio::time::sleep(Duration::from_millis(20)) => {
                if net(&shared).generation != generation {
                    return;
                }
                continue;
            }
        };
        let Some((due, bytes)) = next else {
            let _ = to.shutdown().await;
            return;
        };
        tokio::time::sleep_until(due.max(free_at)).await;
        wait_while_stopped(&shared, dir).await;
        let n = net(&shared);
        if n.generation != generation {
            return;
        }
        if to.write_all(&bytes).await.is_err() {
            return;
        }
        free_at = Instant::now();
        if n.rate > 0 {
            free_at += Duration::from_secs_f64(bytes.len() as f64 / n.rate as f64);
        }
    }
}

async fn wait_while_stopped(shared: &Shared, dir: usize) {
    loop {
        let n = net(shared);
        let now = Instant::now();
        match n.stalled_until[dir] {
            _ if n.blackhole => tokio::time::sleep(Duration::from_millis(50)).await,
            Some(t) if t > now => tokio::time::sleep_until(t).await,
            _ => return,
        }
    }
}
