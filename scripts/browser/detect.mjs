// Opens the built web studio (app/dist, served on localhost) on the Detect panel with a shipped
// sample, waits for the detector's console line, prints it, and screenshots the page.
//   node scripts/browser/detect.mjs URL OUT.png
// The studio logs "detected N marker(s) in NAME (W×H) in T ms (propose …, verify …, read …, reconcile …; …)" when a
// detection finishes (app/src/studio/detect.rs); the time is performance.now() in the page.
import { chromium } from "playwright-core";

const [url, out] = process.argv.slice(2);
if (!url || !out) {
  console.error("usage: node detect.mjs URL OUT.png");
  process.exit(2);
}
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium",
  args: [
    "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
    "--disable-quic", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync",
  ],
});
let failed = false;
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 900 } });
  // Every animation frame's time from the first one on: the longest gap between two frames is the
  // longest the page stood still (a detection on the UI thread draws nothing until it ends).
  await page.addInitScript(() => {
    window.__frames = [];
    const tick = (t) => {
      window.__frames.push(t);
      requestAnimationFrame(tick);
    };
    requestAnimationFrame(tick);
  });
  const lines = [];
  page.on("console", (m) => lines.push(m.text()));
  page.on("pageerror", (e) => lines.push(`page error: ${e.message}`));
  await page.goto(url);
  const deadline = Date.now() + 120_000;
  let detected;
  while (!(detected = lines.find((l) => l.includes("detected "))) && Date.now() < deadline) {
    if (lines.some((l) => l.startsWith("page error") || l.includes("panicked"))) break;
    await page.waitForTimeout(200);
  }
  if (detected) {
    console.log(detected);
    // Let a few frames draw the result before the picture is taken.
    await page.waitForTimeout(1500);
    const frames = await page.evaluate(() => window.__frames);
    const gaps = frames.slice(1).map((t, i) => t - frames[i]).sort((a, b) => a - b);
    if (gaps.length > 0) {
      const first = frames[0];
      console.log(
        `frames: ${frames.length}, first at ${first.toFixed(0)} ms; frame time median ` +
          `${gaps[Math.floor(gaps.length / 2)].toFixed(1)} ms, longest ${gaps[gaps.length - 1].toFixed(0)} ms`,
      );
    }
  } else {
    failed = true;
    console.error("no detection was logged; the page said:\n" + lines.join("\n"));
  }
  await page.screenshot({ path: out });
} finally {
  await browser.close();
}
process.exit(failed ? 1 : 0);
