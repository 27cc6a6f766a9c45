//! The browser entry point: the same studio on the `tagsmith_canvas` canvas of `app/index.html`.

use crate::studio::files::WebFiles;
use crate::studio::StudioApp;
use wasm_bindgen::JsCast;

pub fn start() {
    eframe::WebLogger::init(log::LevelFilter::Info).ok();
    wasm_bindgen_futures::spawn_local(async {
        let canvas = web_sys::window()
            .and_then(|w| w.document())
            .and_then(|d| d.get_element_by_id("tagsmith_canvas"))
            .and_then(|e| e.dyn_into::<web_sys::HtmlCanvasElement>().ok())
            .expect("index.html has a <canvas id=\"tagsmith_canvas\">");
        let started = eframe::WebRunner::new()
            .start(
                canvas,
                eframe::WebOptions::default(),
                Box::new(|cc| Ok(Box::new(StudioApp::new(cc, Box::new(WebFiles::default()))))),
            )
            .await;
        if let Err(e) = started {
            log::error!("the studio could not start: {e:?}");
        }
    });
}
