//! Contours (50) and sector blanking (51) take effect on the next azimuths: a contour value
//! v sends v bins (Navtech's `colossus_protocol_test` sends 100 and counts 100); by default
//! they are the radar's and outlive the connection that sent them, with
//! `ShapingScope::Connection` that client's only; a contour whose last bytes could start a
//! frame signature (`00 01`) takes effect though the client sends nothing after it; a
//! malformed update is refused and costs nothing else; a contoured stream (21) and a
//! non-contoured one (140) differ exactly there; an empty blanking update clears the radar's
//! blanking. Navtech's tester itself (not in the repository) scores 21 of 21 against the
//! simulator (README, "Navtech's protocol tester"); these test its checks directly.

mod common;

use std::time::Duration;

use common::TestClient;
use protocol::{BlankingSector, ContourUpdate, Message, SectorBlanking};
use sim_sensor::scene::shipped;
use sim_sensor::{ShapingScope, SimHandle, SimOptions, SimServer};
use tokio::io::AsyncWriteExt;

const BOUND: Duration = Duration::from_secs(30);

/// Bins and azimuth (degrees) of the next `n` FFT frames.
async fn azimuths(client: &mut TestClient, n: usize, encoder_size: u16) -> Vec<(f64, usize)> {
    let mut out = Vec::new();
    while out.len() < n {
        if let Message::FftData(fft) = client.next().await {
            let deg = f64::from(fft.azimuth) * 360.0 / f64::from(encoder_size);
            out.push((deg, fft.bins.len()));
        }
    }
    out
}

/// A simulator of the outdoor field and one client past the handshake, with the encoder
/// size and bins per azimuth its configuration announced.
async fn connected() -> (SimHandle, TestClient, u16, usize) {
    connected_with(ShapingScope::Radar).await
}

async fn connected_with(scope: ShapingScope) -> (SimHandle, TestClient, u16, usize) {
    let scene = shipped::load("outdoor-field").expect("scene");
    let mut options = SimOptions::for_tests(scene);
    options.shaping_scope = scope;
    let handle = SimServer::spawn(options).await.expect("spawn");
    let mut client = TestClient::connect(handle.local_addr()).await;
    let config = client.configuration().await;
    let (encoder, bins) = (config.encoder_size, usize::from(config.range_in_bins));
    (handle, client, encoder, bins)
}

fn contour_of(max_bin: u16) -> ContourUpdate {
    ContourUpdate::MaxBinPerDegree(Box::new([max_bin; 360]))
}

#[tokio::test]
async fn a_connections_contour_shortens_a_contoured_stream_for_that_client_only() {
    tokio::time::timeout(BOUND, async {
        let (handle, mut shaped, encoder, bins) = connected_with(ShapingScope::Connection).await;
        let mut plain = TestClient::connect(handle.local_addr()).await;
        plain.configuration().await;
        shaped.send(Message::ContourUpdate(contour_of(100))).await;
        shaped.send(Message::StartFftData).await;
        plain.send(Message::StartFftData).await;
        // The contour arrived before the start: every azimuth is cut to bins 0..100 (100
        // bins, as Navtech's tester counts; 101 before).
        let cut = azimuths(&mut shaped, 50, encoder).await;
        assert!(cut.iter().all(|&(_, n)| n == 100), "{cut:?}");
        // The other client on the same simulator is unaffected.
        let full = azimuths(&mut plain, 50, encoder).await;
        assert!(full.iter().all(|&(_, n)| n == bins), "{full:?}");
        // An empty contour resets: full length again on the next azimuths.
        shaped
            .send(Message::ContourUpdate(ContourUpdate::Reset))
            .await;
        let mut later = azimuths(&mut shaped, 400, encoder).await;
        later.retain(|&(_, n)| n == bins);
        assert!(!later.is_empty(), "the reset never took effect");
    })
    .await
    .expect("bounded");
}

#[tokio::test]
async fn a_non_contoured_stream_ignores_the_contour_and_a_blanked_sector_sends_no_bins() {
    tokio::time::timeout(BOUND, async {
        let (_handle, mut client, encoder, bins) = connected().await;
        client.send(Message::ContourUpdate(contour_of(99))).await;
        client
            .send(Message::SectorBlankingUpdate(SectorBlanking {
                sectors: vec![BlankingSector::from_degrees(90.0, 180.0)],
            }))
            .await;
        client.send(Message::StartNonContourFftData).await;
        let got = azimuths(&mut client, 250, encoder).await;
        for (deg, n) in &got {
            if (90.0..180.0).contains(deg) {
                assert_eq!(*n, 0, "blanked at {deg} degrees");
            } else {
                assert_eq!(*n, bins, "140 keeps full length at {deg} degrees");
            }
        }
        assert!(got.iter().any(|(d, _)| (90.0..180.0).contains(d)));
    })
    .await
    .expect("bounded");
}

#[tokio::test]
async fn a_malformed_contour_or_blanking_update_is_refused_and_the_session_goes_on() {
    tokio::time::timeout(BOUND, async {
        let (_handle, mut client, encoder, bins) = connected().await;
        // A contour payload of the wrong length (10 bytes instead of 720).
        let mut frame = bytes::BytesMut::new();
        protocol::encode_raw_frame(&mut frame, protocol::message_id::CONTOUR_UPDATE, &[0u8; 10])
            .expect("frame");
        client.stream.write_all(&frame).await.expect("send");
        // Blanking angles out of range.
        client
            .send(Message::SectorBlankingUpdate(SectorBlanking {
                sectors: vec![BlankingSector::from_degrees(10.0, 720.0)],
            }))
            .await;
        client.send(Message::StartFftData).await;
        let got = azimuths(&mut client, 100, encoder).await;
        assert!(got.iter().all(|&(_, n)| n == bins), "{got:?}");
    })
    .await
    .expect("bounded");
}

#[tokio::test]
async fn the_radars_contour_and_blanking_outlive_the_connection_that_set_them() {
    tokio::time::timeout(BOUND, async {
        let (handle, mut setter, encoder, _) = connected().await;
        setter.send(Message::ContourUpdate(contour_of(100))).await;
        setter
            .send(Message::SectorBlankingUpdate(SectorBlanking {
                sectors: vec![BlankingSector::from_degrees(0.0, 90.0)],
            }))
            .await;
        // Both taken before the connection closes: its own stream shows them.
        setter.send(Message::StartFftData).await;
        let seen = azimuths(&mut setter, 20, encoder).await;
        assert!(
            seen.iter()
                .all(|&(d, n)| n == if d < 90.0 { 0 } else { 100 }),
            "{seen:?}"
        );
        drop(setter);
        // The next connection's stream is shaped by them (before: full length).
        let mut next = TestClient::connect(handle.local_addr()).await;
        next.configuration().await;
        next.send(Message::StartFftData).await;
        let got = azimuths(&mut next, 400, encoder).await;
        for &(deg, n) in &got {
            assert_eq!(n, if deg < 90.0 { 0 } else { 100 }, "at {deg} degrees");
        }
        assert!(got.iter().any(|&(d, _)| d < 90.0) && got.iter().any(|&(d, _)| d >= 90.0));
    })
    .await
    .expect("bounded");
}

#[tokio::test]
async fn a_contour_whose_last_bytes_could_start_a_signature_takes_effect_with_nothing_after_it() {
    tokio::time::timeout(BOUND, async {
        let (_handle, mut client, encoder, bins) = connected().await;
        client.send(Message::StartFftData).await;
        let before = azimuths(&mut client, 20, encoder).await;
        assert!(before.iter().all(|&(_, n)| n == bins), "{before:?}");
        // The last degree's value 1 ends the frame in 00 01, the start of a signature; the
        // client sends nothing more (as Navtech's clients do). Before, the simulator held the
        // contour until more bytes came: never.
        let mut contour = Box::new([100u16; 360]);
        contour[359] = 1;
        client
            .send(Message::ContourUpdate(ContourUpdate::MaxBinPerDegree(
                contour,
            )))
            .await;
        let deadline = std::time::Instant::now() + Duration::from_secs(5);
        let mut cut = false;
        while !cut && std::time::Instant::now() < deadline {
            let got = azimuths(&mut client, 100, encoder).await;
            cut = got.iter().any(|&(d, n)| d < 359.0 && n == 100);
        }
        assert!(cut, "the contour did not take effect within 5 s");
    })
    .await
    .expect("bounded");
}

#[tokio::test]
async fn a_client_that_closes_its_sending_side_after_asking_still_gets_the_data() {
    tokio::time::timeout(BOUND, async {
        let (_handle, mut client, encoder, bins) = connected().await;
        client.send(Message::StartFftData).await;
        client.stream.shutdown().await.expect("shutdown(SHUT_WR)");
        // Before: the configuration and what was in flight, then the connection closed.
        let got = azimuths(&mut client, 2000, encoder).await;
        assert!(got.iter().all(|&(_, n)| n == bins));
    })
    .await
    .expect("bounded");
}

#[tokio::test]
async fn an_empty_blanking_update_clears_the_radars_blanking_for_later_connections() {
    // Navtech's tester blanks 0-90 and 180-270 degrees and never clears it: the radar keeps
    // it, so a second run against the same simulator sees zero-bin azimuths in its
    // full-length checks. A blanking update with no sectors clears it (sim-sensor README).
    tokio::time::timeout(BOUND, async {
        let (handle, mut setter, encoder, bins) = connected().await;
        setter
            .send(Message::SectorBlankingUpdate(SectorBlanking {
                sectors: vec![
                    BlankingSector::from_degrees(0.0, 90.0),
                    BlankingSector::from_degrees(180.0, 270.0),
                ],
            }))
            .await;
        setter.send(Message::StartNonContourFftData).await;
        let blanked = azimuths(&mut setter, 400, encoder).await;
        assert!(blanked.iter().any(|&(_, n)| n == 0), "{blanked:?}");
        drop(setter);

        let mut clearer = TestClient::connect(handle.local_addr()).await;
        clearer.configuration().await;
        clearer
            .send(Message::SectorBlankingUpdate(SectorBlanking {
                sectors: vec![],
            }))
            .await;
        // The update is taken when it arrives; the start after it proves it was read.
        clearer.send(Message::StartNonContourFftData).await;
        azimuths(&mut clearer, 1, encoder).await;
        drop(clearer);

        let mut next = TestClient::connect(handle.local_addr()).await;
        next.configuration().await;
        next.send(Message::StartNonContourFftData).await;
        let got = azimuths(&mut next, 400, encoder).await;
        assert!(got.iter().all(|&(_, n)| n == bins), "{got:?}");
        assert!(got.iter().any(|&(d, _)| d < 90.0) && got.iter().any(|&(d, _)| d >= 180.0));
    })
    .await
    .expect("bounded");
}
