// What the browser checks share: headless Chromium on the built studio, with every animation
// frame's time, the page thread's long tasks and the studio's log lines recorded on the page's
// clock, and the summaries the checks print.
import { chromium } from "playwright-core";

export async function launch() {
  return chromium.launch({
    executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium",
    args: [
      "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
      "--disable-quic", "--no-first-run", "--disable-background-networking",
      "--disable-component-update", "--disable-sync",
    ],
  });
}

// A 1400×900 page, recording from its first script on. `lines` collects the console as it
// comes (to wait on); the recorded frames and logs are read back with `recorded`.
export async function openRecorded(browser) {
  const page = await browser.newPage({ viewport: { width: 1400, height: 900 } });
  // The longest gap between two animation frames is the longest the page stood still.
  await page.addInitScript(() => {
    window.__frames = [];
    window.__logs = [];
    const tick = (t) => {
      window.__frames.push(t);
      requestAnimationFrame(tick);
    };
    requestAnimationFrame(tick);
    // Tasks of 50 ms or more on the page's own thread: a frame gap without one is the browser
    // waiting for a core (a worker holds one of this machine's two), not the studio's code.
    window.__long = [];
    new PerformanceObserver((list) => {
      for (const e of list.getEntries()) window.__long.push([e.startTime, e.duration]);
    }).observe({ type: "longtask", buffered: true });
    for (const level of ["log", "info", "debug", "warn", "error"]) {
      const original = console[level].bind(console);
      console[level] = (...args) => {
        window.__logs.push([performance.now(), args.map(String).join(" ")]);
        original(...args);
      };
    }
  });
  const lines = [];
  page.on("console", (m) => lines.push(m.text()));
  page.on("pageerror", (e) => lines.push(`page error: ${e.message}`));
  return { page, lines };
}

// Polls `lines` until `done(lines)` holds, the page fails, or `seconds` pass; true when done.
export async function waitFor(page, lines, done, seconds) {
  const deadline = Date.now() + seconds * 1000;
  while (!done(lines) && Date.now() < deadline) {
    if (lines.some((l) => l.startsWith("page error") || l.includes("panicked"))) return false;
    await page.waitForTimeout(200);
  }
  return done(lines);
}

export async function recorded(page) {
  return page.evaluate(() => ({
    frames: window.__frames,
    logs: window.__logs,
    paint: performance.getEntriesByType("paint").map((e) => [e.name, e.startTime]),
    long: window.__long,
  }));
}

// Sorted gaps between consecutive frame times.
export const gaps = (list) => list.slice(1).map((t, i) => t - list[i]).sort((a, b) => a - b);

export const summary = (g) =>
  g.length === 0
    ? "no frames"
    : `median ${g[Math.floor(g.length / 2)].toFixed(1)} ms, p99 ` +
      `${g[Math.min(g.length - 1, Math.floor(g.length * 0.99))].toFixed(1)} ms, longest ` +
      `${g[g.length - 1].toFixed(1)} ms`;

// The frames from the one before `from` to the one after `to`.
export const framesIn = (frames, from, to) =>
  frames.filter((t, i) => frames[i + 1] >= from && (frames[i - 1] ?? 0) <= to);

// The longest gaps among `during`, with where they fall from `from`.
export const worstGaps = (during, from, k = 3) =>
  during
    .slice(1)
    .map((t, i) => [t - during[i], during[i] - from])
    .sort((a, b) => b[0] - a[0])
    .slice(0, k)
    .map(([gap, at]) => `${gap.toFixed(0)} ms at ${at >= 0 ? "+" : ""}${at.toFixed(0)} ms`)
    .join(", ");

export const longIn = (long, from, to) => {
  const tasks = long.filter(([t, d]) => t + d >= from && t <= to);
  return tasks.length === 0
    ? "no long task on the page's thread"
    : `long tasks on the page's thread: ${tasks
        .map(([t, d]) => `${d.toFixed(0)} ms at ${t >= from ? "+" : ""}${(t - from).toFixed(0)} ms`)
        .join(", ")}`;
};

// The times of the log lines that contain `text`.
export const logged = (logs, text) => logs.filter(([, line]) => line.includes(text)).map(([t]) => t);
