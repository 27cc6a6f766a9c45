// Opens the built web studio (app/dist, served on localhost) on the Detect panel with a shipped
// sample, waits for the detector's console line, prints it, and screenshots the page.
//   node scripts/browser/detect.mjs URL OUT.png
// The studio logs "detecting NAME in the background" when it hands the image to its worker and
// "detected N marker(s) in NAME (W×H) in T ms (propose …, verify …, read …, reconcile …; …)"
// when the result is back (app/src/studio/detect.rs); T is the worker's own detection time.
// Printed besides: the page's first paint, the wall time from hand-over to result, and the
// animation frames in between (the UI thread must keep drawing while the worker detects).
// It detects twice: on opening (the worker loading the module meanwhile), then the same sample
// again through a new address (#detect=NAME~2). Exits 1 when a detection is not logged, or when
// MAX_FRAME_MS is set and a frame gap during the second detection is longer. Two controls follow:
// a worker spinning beside the idle page (frame gaps the machine makes on its own) and the studio
// redrawing as the mouse moves with no detection (what one frame of the page costs here); the
// page thread's long tasks are listed for each span.
import {
  framesIn, gaps, launch, logged, longIn, openRecorded, recorded, summary, waitFor, worstGaps,
} from "./page.mjs";

const [url, out] = process.argv.slice(2);
if (!url || !out) {
  console.error("usage: node detect.mjs URL OUT.png");
  process.exit(2);
}
const browser = await launch();
let failed = false;
try {
  const { page, lines } = await openRecorded(browser);
  const detections = (l) => l.filter((line) => line.includes("detected "));
  await page.goto(url);
  if (await waitFor(page, lines, (l) => detections(l).length >= 1, 120)) {
    console.log(detections(lines)[0]);
    // The same sample again through a new address: the worker has loaded the module by now,
    // so these frames show the page during a detection alone.
    await page.evaluate(() => {
      location.hash += "~2";
    });
    if (await waitFor(page, lines, (l) => detections(l).length >= 2, 120)) {
      console.log(detections(lines)[1]);
    }
    // Let a few frames draw the result before the picture is taken.
    await page.waitForTimeout(1500);
    // The control: a worker that only spins for as long as a detection, the page idle, so that
    // frame gaps the machine makes on its own are told from the studio's.
    const spin = await page.evaluate(async () => {
      const code = "onmessage = (e) => { const end = performance.now() + e.data; " +
        "while (performance.now() < end) {} postMessage(0); };";
      const worker = new Worker(URL.createObjectURL(new Blob([code])));
      const from = performance.now();
      await new Promise((done) => {
        worker.onmessage = done;
        worker.postMessage(1500);
      });
      worker.terminate();
      return [from, performance.now()];
    });
    // The second control: the studio redrawing (the mouse moving over it), no detection running:
    // what a frame of this page costs on this machine's software renderer.
    const redrawFrom = await page.evaluate(() => performance.now());
    for (let k = 0; k < 60; k++) {
      await page.mouse.move(200 + 15 * k, 300 + 5 * (k % 7));
      await page.waitForTimeout(16);
    }
    const redrawTo = await page.evaluate(() => performance.now());
    const { frames, logs, paint, long } = await recorded(page);
    const firstPaint = paint.find(([name]) => name === "first-contentful-paint") ?? paint[0];
    console.log(`first paint: ${firstPaint ? firstPaint[1].toFixed(0) + " ms" : "not reported"}`);
    console.log(`all frames: ${frames.length}; ${summary(gaps(frames))}`);
    const [starts, ends] = [logged(logs, "in the background"), logged(logs, "detected ")];
    const limit = Number(process.env.MAX_FRAME_MS);
    for (const [k, label] of ["first (the worker starting)", "again (the worker ready)"].entries()) {
      const [from, to] = [starts[k], ends[k]];
      if (from === undefined || to === undefined) {
        console.log(`${label}: not logged`);
        failed ||= k === 1;
        continue;
      }
      const during = framesIn(frames, from, to);
      const g = gaps(during);
      // Where the longest gaps fall, from the hand-over: a slow frame at the start or the end
      // is the UI's own work (opening the image, drawing the result), not the detection.
      console.log(
        `${label}: ${(to - from).toFixed(0)} ms from hand-over to result, ${during.length} ` +
          `frames; ${summary(g)}; longest gaps ${worstGaps(during, from)}; ` +
          longIn(long, from, to),
      );
      if (k === 1 && limit > 0 && g.length > 0 && g[g.length - 1] > limit) {
        console.error(`a frame gap of ${g[g.length - 1].toFixed(1)} ms during the detection (limit ${limit} ms)`);
        failed = true;
      }
    }
    console.log(
      `control, a worker spinning ${(spin[1] - spin[0]).toFixed(0)} ms beside the idle page: ` +
        `${summary(gaps(framesIn(frames, ...spin)))}; ${longIn(long, ...spin)}`,
    );
    console.log(
      `control, the studio redrawing as the mouse moves, no detection: ` +
        `${summary(gaps(framesIn(frames, redrawFrom, redrawTo)))}; ` +
        longIn(long, redrawFrom, redrawTo),
    );
  } else {
    failed = true;
    console.error("no detection was logged; the page said:\n" + lines.join("\n"));
  }
  await page.screenshot({ path: out });
} finally {
  await browser.close();
}
process.exit(failed ? 1 : 0);
