//! What the wire sends must not flood the log: a radar re-sending its configuration a
//! thousand times gets one INFO line per change (an unusable configuration ends the
//! connection: `tests/handshake.rs`; undecodable ones are rate-limited: `tests/logging.rs`).

mod common;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use common::*;
use protocol::Message;
use radar_driver::Driver;
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::layer::{Context, SubscriberExt};
use tracing_subscriber::Layer;

/// Counts INFO and WARN events.
#[derive(Clone, Default)]
struct Counts {
    info: Arc<AtomicUsize>,
    warn: Arc<AtomicUsize>,
}

impl<S: Subscriber> Layer<S> for Counts {
    fn on_event(&self, event: &Event<'_>, _ctx: Context<'_, S>) {
        match *event.metadata().level() {
            Level::INFO => self.info.fetch_add(1, Ordering::Relaxed),
            Level::WARN => self.warn.fetch_add(1, Ordering::Relaxed),
            _ => 0,
        };
    }
}

#[tokio::test]
async fn a_radar_resending_its_configuration_a_thousand_times_is_logged_once() {
    let counts = Counts::default();
    let _guard =
        tracing::subscriber::set_default(tracing_subscriber::registry().with(counts.clone()));
    tokio::time::timeout(Duration::from_secs(30), async {
        let radar = FakeRadar::bind().await;
        let (driver, rx) = Driver::new(test_settings(radar.addr));
        let handle = driver.spawn();
        let config = small_configuration();
        let mut conn = radar.accept().await;
        conn.handshake(&config).await;
        let info_after_handshake = counts.info.load(Ordering::Relaxed);
        for _ in 0..1000 {
            conn.send_message(&Message::Configuration(Box::new(config.clone())))
                .await;
        }
        send_ffts(&mut conn, &config, 0..4).await;
        take_async(rx.azimuths.as_ref().unwrap(), 4).await;
        let m = handle.stop().await.unwrap().metrics;
        assert!(m.configurations >= 1001, "{}", m.configurations);
        let info = counts.info.load(Ordering::Relaxed) - info_after_handshake;
        let warn = counts.warn.load(Ordering::Relaxed);
        assert!(
            info <= 10,
            "{info} INFO lines for 1000 repeated configurations"
        );
        assert_eq!(
            warn, 0,
            "{warn} WARN lines for repeated, valid configurations"
        );
    })
    .await
    .expect("bounded");
}
