//! Fuzz the payload decoders directly: first byte the message id, the rest the payload.
//! Whatever decodes must re-encode to a frame that decodes to the same bytes.
#![no_main]

use bytes::{Bytes, BytesMut};
use libfuzzer_sys::fuzz_target;
use protocol::{FrameDecoder, Message};

fuzz_target!(|data: &[u8]| {
    let Some((&id, payload)) = data.split_first() else {
        return;
    };
    if let Ok(m) = Message::decode_payload(id, Bytes::copy_from_slice(payload)) {
        let first = m.to_bytes().expect("a decoded message encodes");
        let mut buf = BytesMut::from(&first[..]);
        let again = FrameDecoder::new()
            .decode_eof(&mut buf)
            .expect("its encoding decodes")
            .expect("whole");
        assert_eq!(again.to_bytes().expect("encodes"), first);
    }
});
