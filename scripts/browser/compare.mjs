// Opens the built web studio on the Compare panel running a comparison in its web worker
// (`#compare=FAMILY,FAMILY&scenes=N`, app/src/web.rs), waits for its end, prints the frames the
// page drew meanwhile, and screenshots the plots and table.
//   node scripts/browser/compare.mjs URL OUT.png
// The studio logs "comparing … in the background" when it starts the worker and "comparison
// finished: N scenes per design" at the end (app/src/studio/compare.rs). Exits 1 when the run
// does not finish within 10 minutes or the page fails, or when MAX_FRAME_MS is set and a frame
// gap during the run is longer.
import {
  framesIn, gaps, launch, logged, openRecorded, recorded, summary, waitFor, worstGaps,
} from "./page.mjs";

const [url, out] = process.argv.slice(2);
if (!url || !out) {
  console.error("usage: node compare.mjs URL OUT.png");
  process.exit(2);
}
const browser = await launch();
let failed = false;
try {
  const { page, lines } = await openRecorded(browser);
  await page.goto(url);
  const ended = (l) => l.some((line) => line.includes("comparison finished") || line.includes("comparison stopped"));
  if (await waitFor(page, lines, ended, 600)) {
    console.log(lines.find((l) => l.includes("comparison ")));
    // Let the last snapshot draw before the picture is taken.
    await page.waitForTimeout(1500);
    const { frames, logs, long } = await recorded(page);
    const [from, to] = [logged(logs, "in the background")[0], logged(logs, "comparison ")[0]];
    failed = lines.some((l) => l.includes("comparison stopped"));
    if (from !== undefined && to !== undefined) {
      const during = framesIn(frames, from, to);
      const g = gaps(during);
      console.log(
        `the run: ${((to - from) / 1000).toFixed(1)} s, ${during.length} frames; ${summary(g)}; ` +
          `longest gaps ${worstGaps(during, from)}; ` +
          `${long.filter(([t, d]) => t + d >= from && t <= to).length} long tasks on the page's thread`,
      );
      const limit = Number(process.env.MAX_FRAME_MS);
      if (limit > 0 && g.length > 0 && g[g.length - 1] > limit) {
        console.error(`a frame gap of ${g[g.length - 1].toFixed(1)} ms during the run (limit ${limit} ms)`);
        failed = true;
      }
    } else {
      console.log("the run's start or end was not logged");
    }
  } else {
    failed = true;
    console.error("the comparison did not finish; the page said:\n" + lines.join("\n"));
  }
  await page.screenshot({ path: out });
} finally {
  await browser.close();
}
process.exit(failed ? 1 : 0);
