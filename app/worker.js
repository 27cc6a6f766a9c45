// The studio's detection worker (app/src/studio/offload/web.rs): the same wasm module as the
// page; its main sees a worker's scope and serves detection requests instead of drawing.
import init from "./tagsmith.js";
init();
