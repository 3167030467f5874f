//! The live view page (`[output.view]`, `--view`), embedded: `view/index.html` and
//! `view/view.js`, the latter bundled by esbuild from `slam-node/view/src/main.js` with
//! Foxglove's WebSocket client (`@foxglove/ws-protocol`) and protobufjs (`npm ci && npm run
//! build` in `slam-node/view`; the bundle is committed, so the Rust build needs no npm). The
//! page connects to the WebSocket of the address that served it and draws the radar image,
//! the map, the trajectory and the pose on two canvases.

use super::gate::Asset;

/// The page and its script.
pub const ASSETS: &[Asset] = &[
    Asset {
        path: "/",
        content_type: "text/html; charset=utf-8",
        body: include_bytes!("view/index.html"),
    },
    Asset {
        path: "/index.html",
        content_type: "text/html; charset=utf-8",
        body: include_bytes!("view/index.html"),
    },
    // Browsers ask for it; an empty answer rather than a 404 counted as a bad request.
    Asset {
        path: "/favicon.ico",
        content_type: "image/x-icon",
        body: b"",
    },
    Asset {
        path: "/view.js",
        content_type: "text/javascript; charset=utf-8",
        body: include_bytes!("view/view.js"),
    },
];
