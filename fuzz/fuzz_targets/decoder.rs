//! Fuzz the streaming decoder: the input's first byte picks a chunk size, the rest is the
//! stream, fed in chunks, then finished with `decode_eof`. Checks: no panic, no stall
//! (every call consumes bytes or asks for more, and asking for more consumes nothing),
//! every byte accounted for, and every decoded message re-encodes to bytes that decode to
//! the same bytes.
#![no_main]

use bytes::BytesMut;
use libfuzzer_sys::fuzz_target;
use protocol::{FrameDecoder, Message};

fn check_reencoding(m: &Message) {
    let first = m.to_bytes().expect("a decoded message encodes");
    let mut buf = BytesMut::from(&first[..]);
    let again = FrameDecoder::new()
        .decode_eof(&mut buf)
        .expect("its encoding decodes")
        .expect("whole");
    assert!(buf.is_empty());
    assert_eq!(again.to_bytes().expect("encodes"), first);
}

fn drain(decoder: &mut FrameDecoder, buf: &mut BytesMut, eof: bool) {
    loop {
        let before = buf.len();
        let result = if eof {
            decoder.decode_eof(buf)
        } else {
            decoder.decode(buf)
        };
        match result {
            Ok(Some(m)) => check_reencoding(&m),
            Ok(None) => {
                assert_eq!(buf.len(), before, "Ok(None) consumed bytes");
                return;
            }
            Err(_) => {}
        }
        assert!(buf.len() < before, "no progress");
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&chunk_byte, stream)) = data.split_first() else {
        return;
    };
    let chunk = usize::from(chunk_byte) * 8 + 1;
    let mut decoder = FrameDecoder::new();
    let mut buf = BytesMut::new();
    for piece in stream.chunks(chunk) {
        buf.extend_from_slice(piece);
        drain(&mut decoder, &mut buf, false);
    }
    drain(&mut decoder, &mut buf, true);
    assert_eq!(
        decoder.stats().bytes_consumed() + buf.len() as u64,
        stream.len() as u64
    );
});
