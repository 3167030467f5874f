//! Real data through the codec: every azimuth of the eight Oxford Radar RobotCar scans
//! (CTS350-X, `../shared/data/oxford-radar-robotcar/`) is put on the wire as an 8-bit FFT
//! frame, the stream is decoded in 4 KiB reads, and what comes out must be the recorded
//! bins, encoder values and timestamps, with angles 0.9 degrees apart. Real bins
//! must not trip cut-short detection. Skipped, with a message, when the data is absent.

use std::fs::File;
use std::path::PathBuf;

use bytes::BytesMut;
use protocol::{
    azimuth_to_deg, bin8_to_db, encode_fft_frame, BinWidth, FrameDecoder, Message, Timestamp,
};

const WIDTH: usize = 3779;
const ROWS: usize = 400;
const FIRST_BIN_COLUMN: usize = 11;

fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/oxford-radar-robotcar/radar")
}

struct Row {
    timestamp_us: i64,
    encoder: u16,
    bins: Vec<u8>,
}

fn read_scan(path: &PathBuf) -> Vec<Row> {
    let decoder = png::Decoder::new(File::open(path).expect("scan opens"));
    let mut reader = decoder.read_info().expect("PNG header");
    let mut pixels = vec![0u8; reader.output_buffer_size()];
    let info = reader.next_frame(&mut pixels).expect("PNG pixels");
    assert_eq!((info.width as usize, info.height as usize), (WIDTH, ROWS));
    assert_eq!(info.color_type, png::ColorType::Grayscale);
    pixels
        .chunks_exact(info.line_size)
        .map(|row| Row {
            timestamp_us: i64::from_le_bytes(row[0..8].try_into().unwrap()),
            encoder: u16::from_le_bytes([row[8], row[9]]),
            bins: row[FIRST_BIN_COLUMN..WIDTH].to_vec(),
        })
        .collect()
}

fn timestamp_of(us: i64) -> Timestamp {
    let seconds = u32::try_from(us.div_euclid(1_000_000)).unwrap();
    let nanos = u32::try_from(us.rem_euclid(1_000_000) * 1000).unwrap();
    Timestamp::new(seconds, nanos).unwrap()
}

#[test]
fn real_cts350x_scans_survive_the_wire_bin_for_bin() {
    let dir = data_dir();
    let Ok(entries) = std::fs::read_dir(&dir) else {
        println!(
            "SKIPPED: no Oxford Radar RobotCar scans at {}",
            dir.display()
        );
        return;
    };
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    paths.sort();
    assert!(!paths.is_empty(), "no scans in {}", dir.display());

    for path in &paths {
        let rows = read_scan(path);
        let mut wire = BytesMut::new();
        for (i, row) in rows.iter().enumerate() {
            let sweep = u16::try_from(i).unwrap();
            let ts = timestamp_of(row.timestamp_us);
            encode_fft_frame(
                &mut wire,
                BinWidth::Eight,
                sweep,
                row.encoder,
                ts,
                &row.bins,
            )
            .unwrap();
        }

        let mut decoder = FrameDecoder::new();
        let mut buf = BytesMut::new();
        let mut decoded = Vec::new();
        for chunk in wire.chunks(4096) {
            buf.extend_from_slice(chunk);
            while let Some(m) = decoder.decode(&mut buf).expect("a clean stream") {
                decoded.push(m);
            }
        }
        while let Some(m) = decoder.decode_eof(&mut buf).expect("a clean stream") {
            decoded.push(m);
        }
        assert!(buf.is_empty());
        assert_eq!(decoded.len(), ROWS, "{}", path.display());
        assert_eq!(decoder.stats().frames_cut_short, 0);

        let mut last_us = i64::MIN;
        let mut last_deg: Option<f64> = None;
        for (row, msg) in rows.iter().zip(&decoded) {
            let Message::FftData(fft) = msg else {
                panic!("not FFT data")
            };
            assert_eq!(&fft.bins[..], &row.bins[..]);
            assert_eq!(fft.azimuth, row.encoder);
            // The recording's grid is offset (13, 27, 41, ...): consecutive azimuths are
            // 14 counts, 0.9 degrees, apart.
            let deg = azimuth_to_deg(fft.azimuth, 5600).unwrap();
            if let Some(prev) = last_deg {
                assert!((deg - prev - 0.9).abs() < 1e-9, "{prev} -> {deg}");
            }
            last_deg = Some(deg);
            let us = (fft.timestamp.as_secs_f64() * 1e6).round() as i64;
            assert!(
                (us - row.timestamp_us).abs() <= 1,
                "{us} vs {}",
                row.timestamp_us
            );
            assert!(
                row.timestamp_us > last_us,
                "timestamps increase within a scan"
            );
            last_us = row.timestamp_us;
            let max = row.bins.iter().copied().max().unwrap();
            let max_db = fft.bins_db().fold(f64::MIN, f64::max);
            assert_eq!(max_db, bin8_to_db(max));
        }
    }
    println!("{} real scans decoded bin for bin", paths.len());
}
