//! The browser entry point: the same studio on the `tagsmith_canvas` canvas of `app/index.html`.

use crate::studio::files::WebFiles;
use crate::studio::StudioApp;
use wasm_bindgen::JsCast;

pub fn start() {
    eframe::WebLogger::init(log::LevelFilter::Info).ok();
    // The detection worker (app/worker.js) runs this same module.
    if crate::studio::offload::web::in_worker() {
        crate::studio::offload::web::serve_in_worker();
        return;
    }
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
                Box::new(|cc| {
                    let mut app = StudioApp::new(cc, Box::new(WebFiles::default()));
                    open_from_address(&mut app);
                    Ok(Box::new(app))
                }),
            )
            .await;
        if let Err(e) = started {
            log::error!("the studio could not start: {e:?}");
        }
    });
}

/// `…/#detect=SAMPLE` opens the Detect panel on that shipped sample: a link that shows the
/// detector at work, and how scripts/web-detect.sh measures it in headless Chromium.
fn open_from_address(app: &mut StudioApp) {
    let hash = web_sys::window()
        .and_then(|w| w.location().hash().ok())
        .unwrap_or_default();
    if let Some(sample) = hash.strip_prefix("#detect=") {
        if !crate::studio::detect::open_sample(&mut app.studio, sample) {
            app.studio
                .error(format!("{sample}: no such sample (see assets/samples/)"));
        }
    }
}
