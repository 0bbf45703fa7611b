//! What every viewer is told, through the protocol: a scheme that blows up is reported and
//! the simulation waits (it used to show 0 cycles a frame and a frozen residual with no
//! message), the pins reach every page, and the hello carries the frame budget the page's
//! meter needs.

use raisov_serve::conn::Limits;
use raisov_serve::protocol::{Command, FLAG_DIVERGED, FLAG_REST, STAT_CYCLES};
use std::time::Duration;

mod common;
use common::{connect, hello, next_frame, next_text, send, start, start_with, CUBE};

/// The cube under gravity at a time step far beyond its stable one: explicit dynamics blows
/// up within a few steps, with no grasp anywhere.
fn unstable_cube() -> String {
    format!("gravity = [0.0, 0.0, -9.81]\n{CUBE}\n[integrator]\ndt = 5e-3\n")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scheme_that_diverges_is_reported_and_waits_for_a_command() {
    let (bound, _task, _) =
        start_with(&unstable_cube(), "127.0.0.1:0", None, Limits::default()).await;
    let addr = bound.to_string();
    let mut ws = connect(&addr).await;
    hello(&mut ws).await;
    let msg = loop {
        let t = next_text(&mut ws).await;
        if t.contains("\"type\":\"error\"") {
            break t;
        }
    };
    assert!(
        msg.contains("single level diverged") && msg.contains("press reset"),
        "{msg}"
    );
    let f = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            let f = next_frame(&mut ws).await;
            if f.flags & FLAG_DIVERGED != 0 {
                return f;
            }
        }
    })
    .await
    .expect("a frame flagged diverged");
    assert_eq!(
        f.stats[STAT_CYCLES], 0.0,
        "the rejected frame is not shown as work"
    );
    // It waits: a frame says so (flagged at rest as well; the newest frame only reaches a
    // client, so it may be the one above), then none follows, instead of the same frame
    // rejected over and over.
    if f.flags & FLAG_REST == 0 {
        let waiting = tokio::time::timeout(Duration::from_secs(5), next_frame(&mut ws))
            .await
            .expect("the frame that says it waits");
        assert_ne!(waiting.flags & FLAG_REST, 0);
        assert_ne!(waiting.flags & FLAG_DIVERGED, 0);
    }
    let more = tokio::time::timeout(Duration::from_secs(1), next_frame(&mut ws)).await;
    assert!(more.is_err(), "frames kept coming after the divergence");
    // A command wakes it; reset starts from rest (and, the step being what it is, it
    // diverges again and says so again).
    send(&mut ws, 1, Command::Reset).await;
    let again = loop {
        let t = next_text(&mut ws).await;
        if t.contains("\"type\":\"error\"") {
            break t;
        }
    };
    assert!(again.contains("diverged"), "{again}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pins_are_sent_to_every_page_and_cleared_by_reset() {
    let (addr, _task) = start().await;
    let mut a = connect(&addr).await;
    let mut b = connect(&addr).await;
    // The hello says the budget and the cap, then the (empty) pins follow.
    let greeting = next_text(&mut a).await;
    assert!(
        greeting.contains("\"budget\":{\"cycles\":20}") && greeting.contains("\"max_fps\":2e2"),
        "{greeting}"
    );
    assert_eq!(next_text(&mut a).await, "{\"type\":\"pins\",\"pins\":[]}");
    hello(&mut b).await;
    send(
        &mut a,
        1,
        Command::Pin {
            point: [0.0, 0.0, 0.04],
            radius: 0.005,
        },
    )
    .await;
    // The other page is told where, with the radius.
    let pins = next_text(&mut b).await;
    assert!(pins.starts_with("{\"type\":\"pins\",\"pins\":[["), "{pins}");
    let nums: Vec<f64> = pins
        .split(['[', ']', ','])
        .filter_map(|x| x.trim().parse().ok())
        .collect();
    assert_eq!(nums, vec![0.0, 0.0, 0.04f32 as f64, 0.005f32 as f64]);
    send(&mut a, 2, Command::Reset).await;
    loop {
        let t = next_text(&mut b).await;
        if t.contains("\"type\":\"pins\"") {
            assert_eq!(t, "{\"type\":\"pins\",\"pins\":[]}");
            break;
        }
    }
    // And a page that connects later is told the pins on connect.
    send(
        &mut a,
        3,
        Command::Pin {
            point: [0.04, 0.04, 0.04],
            radius: 0.0,
        },
    )
    .await;
    loop {
        // (a's queue still holds the first pin's and the reset's messages.)
        let t = next_text(&mut a).await;
        if t.contains("\"type\":\"pins\"") && t.contains("[[3.9") {
            break;
        }
    }
    let mut c = connect(&addr).await;
    assert!(next_text(&mut c).await.contains("hello"));
    let t = next_text(&mut c).await;
    let nums: Vec<f64> = t
        .split(['[', ']', ','])
        .filter_map(|x| x.trim().parse().ok())
        .collect();
    assert_eq!(
        nums,
        vec![0.04f32 as f64, 0.04f32 as f64, 0.04f32 as f64, 0.0],
        "{t}"
    );
}
