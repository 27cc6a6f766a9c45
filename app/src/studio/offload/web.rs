//! The browser's side of the background work: a module worker (`app/worker.js`) that loads the
//! same wasm module as the page. Its `main` sees a worker's global scope and calls
//! [`serve_in_worker`] instead of starting the studio. The page posts `[ticket, request JSON,
//! pixels]` with the pixels' buffer transferred; the worker answers with [`FromWorker`]s as JSON.
//! The Detect panel keeps one worker for its detections ([`Transport`]); each comparison of the
//! Compare panel runs in a worker of its own, which cancelling it ends.

use super::{DetectRequest, Reply, Server, Ticket};
use crate::studio::compare::{self, CompareRequest, Snapshot};
use serde::{Deserialize, Serialize};
use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;
use wasm_bindgen::prelude::*;
use wasm_bindgen::JsCast;

/// What the page asks of a worker.
#[derive(Serialize, Deserialize)]
pub enum ToWorker {
    /// The pixels travel beside the JSON.
    Detect(DetectRequest),
    Compare(CompareRequest),
}

/// What a worker posts back.
#[derive(Serialize, Deserialize)]
pub enum FromWorker {
    /// Its handler is installed: requests posted from now on are read.
    Ready,
    Detected {
        ticket: Ticket,
        // Boxed: a detection's reply is several times larger than the other messages.
        reply: Box<Reply>,
    },
    /// A comparison's report after another scene.
    Compared { ticket: Ticket, snapshot: Snapshot },
    /// A comparison's end.
    Ended {
        ticket: Ticket,
        outcome: Result<(), String>,
    },
    /// Not posted by the worker: the page's word that it failed or could not be read.
    Failed(String),
}

/// Whether this code runs in a dedicated worker rather than a page.
pub fn in_worker() -> bool {
    js_sys::global()
        .dyn_into::<web_sys::DedicatedWorkerGlobalScope>()
        .is_ok()
}

/// The worker's main: loads the assets a comparison's scenes need, then answers each request in
/// turn.
pub fn serve_in_worker() {
    wasm_bindgen_futures::spawn_local(async {
        // The weights are among them: a worker without them says why it can neither detect nor
        // compare.
        let assets = crate::web::load_assets().await;
        if let Err(e) = &assets {
            log::error!("the worker could not load the studio's files: {e}");
        }
        serve(assets);
    });
}

fn serve(assets: Result<(), String>) {
    let scope: web_sys::DedicatedWorkerGlobalScope = js_sys::global().unchecked_into();
    let server = RefCell::new(Server::default());
    let reply_to = scope.clone();
    let on_message =
        Closure::<dyn FnMut(web_sys::MessageEvent)>::new(move |event: web_sys::MessageEvent| {
            let message: js_sys::Array = event.data().unchecked_into();
            let ticket = message.get(0).as_f64().unwrap_or_default() as Ticket;
            let post = |m: &FromWorker| post(&reply_to, m);
            match read_request(&message) {
                Ok(ToWorker::Detect(request)) => {
                    let reply = match &assets {
                        Ok(()) => server.borrow_mut().serve(request),
                        Err(e) => Err(format!("the studio's files did not load: {e}")),
                    };
                    post(&FromWorker::Detected {
                        ticket,
                        reply: Box::new(reply),
                    });
                }
                Ok(ToWorker::Compare(request)) => {
                    let outcome = match &assets {
                        Ok(()) => compare::run_shipped(request, |snapshot| {
                            post(&FromWorker::Compared { ticket, snapshot })
                        }),
                        Err(e) => Err(format!("the studio's files did not load: {e}")),
                    };
                    post(&FromWorker::Ended { ticket, outcome });
                }
                Err(e) => post(&FromWorker::Detected {
                    ticket,
                    reply: Box::new(Err(e)),
                }),
            }
        });
    scope.set_onmessage(Some(on_message.as_ref().unchecked_ref()));
    // The handler lives as long as the worker.
    on_message.forget();
    post(&scope, &FromWorker::Ready);
}

fn read_request(message: &js_sys::Array) -> Result<ToWorker, String> {
    let json = message
        .get(1)
        .as_string()
        .ok_or("the worker got a request without its JSON")?;
    let mut request: ToWorker =
        serde_json::from_str(&json).map_err(|e| format!("the worker's request: {e}"))?;
    if let ToWorker::Detect(detect) = &mut request {
        detect.pixels = js_sys::Uint8Array::new(&message.get(2)).to_vec();
    }
    Ok(request)
}

fn post(scope: &web_sys::DedicatedWorkerGlobalScope, message: &FromWorker) {
    let json = serde_json::to_string(message).expect("replies serialise");
    if let Err(e) = scope.post_message(&JsValue::from_str(&json)) {
        log::error!("the worker could not reply: {e:?}");
    }
}

/// A worker seen from the page. Dropping it ends the worker.
pub struct WebWorker {
    inner: Rc<Inner>,
}

struct Inner {
    handle: web_sys::Worker,
    ready: RefCell<bool>,
    /// Posted once the worker says it is ready.
    waiting: RefCell<Vec<js_sys::Array>>,
    failed: RefCell<Option<String>>,
    // Kept alive with the worker: its handlers.
    _on_message: RefCell<Option<Handler<web_sys::MessageEvent>>>,
    _on_error: RefCell<Option<Handler<web_sys::ErrorEvent>>>,
}

type Handler<Event> = Closure<dyn FnMut(Event)>;

impl WebWorker {
    /// `worker.js` beside the page, as a module worker; `on_message` gets every reply (and
    /// [`FromWorker::Failed`]), and `ctx` repaints after each.
    pub fn spawn(
        ctx: &egui::Context,
        on_message: impl FnMut(FromWorker) + 'static,
    ) -> Result<Self, String> {
        let options = web_sys::WorkerOptions::new();
        options.set_type(web_sys::WorkerType::Module);
        let handle = web_sys::Worker::new_with_options("./worker.js", &options)
            .map_err(|e| format!("the background worker could not start: {e:?}"))?;
        let inner = Rc::new(Inner {
            handle,
            ready: RefCell::new(false),
            waiting: RefCell::new(Vec::new()),
            failed: RefCell::new(None),
            _on_message: RefCell::new(None),
            _on_error: RefCell::new(None),
        });
        let handler = Rc::new(RefCell::new(on_message));
        let (weak, repaint, deliver) = (Rc::downgrade(&inner), ctx.clone(), handler.clone());
        let on_message = Closure::<dyn FnMut(web_sys::MessageEvent)>::new(
            move |event: web_sys::MessageEvent| {
                let Some(inner) = weak.upgrade() else {
                    return;
                };
                let text = event.data().as_string().unwrap_or_default();
                let message = serde_json::from_str::<FromWorker>(&text)
                    .unwrap_or_else(|e| FromWorker::Failed(format!("the worker's reply: {e}")));
                match message {
                    FromWorker::Ready => {
                        *inner.ready.borrow_mut() = true;
                        for waiting in inner.waiting.take() {
                            inner.post(&waiting);
                        }
                    }
                    FromWorker::Failed(e) => {
                        *inner.failed.borrow_mut() = Some(e.clone());
                        (deliver.borrow_mut())(FromWorker::Failed(e));
                    }
                    other => (deliver.borrow_mut())(other),
                }
                repaint.request_repaint();
            },
        );
        let (weak, repaint) = (Rc::downgrade(&inner), ctx.clone());
        let on_error =
            Closure::<dyn FnMut(web_sys::ErrorEvent)>::new(move |event: web_sys::ErrorEvent| {
                let Some(inner) = weak.upgrade() else {
                    return;
                };
                let e = format!("the background worker failed: {}", event.message());
                *inner.failed.borrow_mut() = Some(e.clone());
                (handler.borrow_mut())(FromWorker::Failed(e));
                repaint.request_repaint();
            });
        inner
            .handle
            .set_onmessage(Some(on_message.as_ref().unchecked_ref()));
        inner
            .handle
            .set_onerror(Some(on_error.as_ref().unchecked_ref()));
        *inner._on_message.borrow_mut() = Some(on_message);
        *inner._on_error.borrow_mut() = Some(on_error);
        Ok(Self { inner })
    }

    /// Posts a request, with an image's bytes beside it (moved, not copied), once the worker is
    /// ready.
    pub fn post(&self, ticket: Ticket, request: &ToWorker, pixels: &[u8]) {
        let json = serde_json::to_string(request).expect("requests serialise");
        let message = js_sys::Array::of3(
            &JsValue::from_f64(ticket as f64),
            &json.into(),
            &js_sys::Uint8Array::from(pixels),
        );
        if *self.inner.ready.borrow() {
            self.inner.post(&message);
        } else {
            self.inner.waiting.borrow_mut().push(message);
        }
    }

    /// Why the worker stopped, once it has.
    pub fn failure(&self) -> Option<String> {
        self.inner.failed.borrow().clone()
    }
}

impl Inner {
    fn post(&self, message: &js_sys::Array) {
        let transfer = js_sys::Array::of1(&js_sys::Uint8Array::new(&message.get(2)).buffer());
        if let Err(e) = self.handle.post_message_with_transfer(message, &transfer) {
            *self.failed.borrow_mut() =
                Some(format!("the background worker refused a request: {e:?}"));
        }
    }
}

impl Drop for WebWorker {
    fn drop(&mut self) {
        self.inner.handle.terminate();
        // The handlers hold only weak references; dropping them here ends the cycle.
        self.inner._on_message.take();
        self.inner._on_error.take();
    }
}

/// The Detect panel's worker: started with the panel, so that it has loaded the module by the
/// first request, and started again after a failure.
pub struct Transport {
    ctx: egui::Context,
    worker: Option<WebWorker>,
    replies: Rc<RefCell<VecDeque<(Ticket, Reply)>>>,
}

impl Transport {
    pub fn start(ctx: egui::Context) -> Self {
        let mut transport = Self {
            ctx,
            worker: None,
            replies: Rc::default(),
        };
        if let Err(e) = transport.spawn() {
            log::error!("{e}");
        }
        transport
    }

    fn spawn(&mut self) -> Result<(), String> {
        let replies = self.replies.clone();
        let worker = WebWorker::spawn(&self.ctx, move |message| match message {
            FromWorker::Detected { ticket, reply } => {
                replies.borrow_mut().push_back((ticket, *reply))
            }
            FromWorker::Failed(e) => replies.borrow_mut().push_back((0, Err(e))),
            _ => {}
        })?;
        self.worker = Some(worker);
        Ok(())
    }

    pub fn send(&mut self, ticket: Ticket, mut request: DetectRequest) {
        if self.worker.as_ref().is_none_or(|w| w.failure().is_some()) {
            self.worker = None;
            self.replies.borrow_mut().clear();
            if let Err(e) = self.spawn() {
                self.replies.borrow_mut().push_back((ticket, Err(e)));
                return;
            }
        }
        let Some(worker) = &self.worker else {
            return;
        };
        let pixels = std::mem::take(&mut request.pixels);
        worker.post(ticket, &ToWorker::Detect(request), &pixels);
    }

    pub fn poll(&mut self, ticket: Ticket) -> Option<Reply> {
        let mut replies = self.replies.borrow_mut();
        while let Some((t, reply)) = replies.pop_front() {
            // Ticket 0: the worker failed, which answers the request in flight.
            if t == ticket || t == 0 {
                return Some(reply);
            }
        }
        None
    }
}
