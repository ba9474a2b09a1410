// The preview's page in a real browser (Debian's chromium, headless, driven
// by playwright-core): `cambium preview` on a copy of the bundled Populus;
// the page loads its picture; its curves are drawn as the reader evaluates
// them; a dragged control point changes the file on disk and brings a new
// picture; an edit of the file on disk updates the page; a bad edit shows
// its error and keeps the picture; requests without the token are refused.
// A screenshot of each step goes to OUT.
//
//   node preview_page.cjs CAMBIUM OUT
// (NODE_PATH: where playwright-core is installed.)  Exit 0: passed; 77:
// skipped (no chromium or playwright-core); else failed.
"use strict";
const fs = require("fs");
const path = require("path");
const http = require("http");
const { spawn } = require("child_process");

const [cambium, out] = process.argv.slice(2);
const chromiumPath = "/usr/bin/chromium";
let playwright;
try {
  playwright = require("playwright-core");
} catch (e) {
  console.log("SKIP: playwright-core is not installed (bash tools/setup.sh test installs it)");
  process.exit(77);
}
if (!fs.existsSync(chromiumPath)) {
  console.log("SKIP: no " + chromiumPath + " (bash tools/setup.sh test installs chromium)");
  process.exit(77);
}

const source = path.join(__dirname, "..", "..", "examples", "populus", "populus.json");
fs.rmSync(out, { recursive: true, force: true });
fs.mkdirSync(out, { recursive: true });
const work = fs.mkdtempSync(path.join(require("os").tmpdir(), "cambium_preview_page_"));
const tree = path.join(work, "tree.json");
fs.copyFileSync(source, tree);

let failures = 0;
function check(ok, what) {
  console.log((ok ? "ok   " : "FAIL ") + what);
  if (!ok) failures++;
}
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
async function until(what, test, seconds = 30) {
  const end = Date.now() + seconds * 1000;
  for (;;) {
    const value = await test();
    if (value) return value;
    if (Date.now() > end) throw new Error("timed out waiting for " + what);
    await sleep(100);
  }
}
// Written beside and renamed over, as editors save.
function save(text) {
  fs.writeFileSync(tree + ".tmp", text);
  fs.renameSync(tree + ".tmp", tree);
}
function get(url) {
  return new Promise((resolve, reject) => {
    http.get(url, (res) => {
      let body = "";
      res.on("data", (d) => (body += d));
      res.on("end", () => resolve({ status: res.statusCode, body }));
    }).on("error", reject);
  });
}

async function main() {
  const preview = spawn(cambium, ["preview", tree, "--time", "5", "--voxel-size", "0.04", "--device", "cpu",
                                  "--width", "480", "--height", "360", "-o", path.join(work, "preview.png")],
                        { stdio: ["ignore", "pipe", "inherit"] });
  let printed = "";
  preview.stdout.on("data", (d) => { printed += d; });
  const exited = new Promise((r) => preview.on("exit", (code, signal) => r(code === null ? signal : code)));
  let browser;
  try {
    const url = (await until("the URL", () => printed.includes("\n") && printed.split("\n")[0])).trim();
    check(/^http:\/\/127\.0\.0\.1:\d+\/\?token=[0-9a-f]{32}$/.test(url), "the first line is the page's URL: " + url);
    const origin = url.replace(/\/\?token=.*/, "");

    browser = await playwright.chromium.launch({
      executablePath: chromiumPath,
      args: ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
             "--disable-component-update", "--disable-sync"],
    });
    const page = await browser.newPage({ viewport: { width: 1400, height: 1000 } });
    const pageErrors = [];
    page.on("pageerror", (e) => pageErrors.push(String(e)));
    await page.goto(url);

    // 1. The picture loads.
    await until("the first picture", () => page.evaluate(() => window.cambium.pictures >= 1 &&
      document.getElementById("picture").naturalWidth === 480), 60);
    check(true, "the first picture is shown");
    await until("the curves", () => page.evaluate(() => Object.keys(window.cambium.editors).length === 13));
    await page.screenshot({ path: path.join(out, "1-first-picture.png") });

    // 2. The page draws each curve as the reader evaluates it.
    const worst = await page.evaluate(() => {
      let worst = 0;
      for (const c of window.cambium.model.curves)
        c.samples.forEach((y, k) => {
          worst = Math.max(worst, Math.abs(window.cambium.curveValue(c.points, c.interpolation, k / 64) - y));
        });
      return worst;
    });
    check(worst < 1e-9, "the page's curves are the reader's (largest difference " + worst + ")");

    // 3. A control point of Gh dragged up: the file changes, a new picture arrives.
    const before = await page.evaluate(() => window.cambium.pictures);
    const at = await page.evaluate(() => {
      const e = window.cambium.editors.Gh, r = e.canvas.getBoundingClientRect();
      return { x: r.left + e.px(e.points[2][0]), y: r.top + e.py(e.points[2][1]), y0: e.points[2][1] };
    });
    await page.mouse.move(at.x, at.y);
    await page.mouse.down();
    for (let i = 1; i <= 5; i++) await page.mouse.move(at.x, at.y - 4 * i);
    await page.mouse.up();
    const dragged = await page.evaluate(() => window.cambium.editors.Gh.points[2]);
    check(dragged[1] > at.y0, `the point moved up in the page (${at.y0} -> ${dragged[1]})`);
    const onDisk = await until("the file to change", () => {
      const gh = JSON.parse(fs.readFileSync(tree, "utf8")).curves.Gh.points;
      return gh[2][1] !== at.y0 && gh;
    });
    check(onDisk[2][0] === dragged[0] && onDisk[2][1] === dragged[1],
          "the file on disk holds the dragged point " + JSON.stringify(onDisk[2]));
    await until("a new picture after the drag", () => page.evaluate((n) => window.cambium.pictures > n, before), 60);
    check(true, "a new picture arrived after the drag");
    const redraw = await page.evaluate(() => Math.max(...window.cambium.redrawMs));
    console.log(`     slowest curve redraw in the page: ${redraw.toFixed(2)} ms`);
    await page.screenshot({ path: path.join(out, "2-after-drag.png") });

    // 4. The file edited on disk: the page follows.
    const pictures = await page.evaluate(() => window.cambium.pictures);
    const text = fs.readFileSync(tree, "utf8");
    const gs1 = /("Gs1": \{"points": )\[\[[^\n]*?\]\]/;
    check(gs1.test(text), "the file's Gs1 as written");
    save(text.replace(gs1, "$1[[0, 0], [0.3, 0.5], [0.8, 0.4], [1, 0.1]]"));
    await until("the page to show the file's Gs1", () => page.evaluate(() =>
      JSON.stringify(window.cambium.editors.Gs1.points) === "[[0,0],[0.3,0.5],[0.8,0.4],[1,0.1]]"), 60);
    check(true, "the page's Gs1 editor shows the file's new points");
    await until("a new picture after the file's edit", () => page.evaluate((n) => window.cambium.pictures > n, pictures), 60);
    check(true, "a new picture arrived after the file's edit");
    await page.screenshot({ path: path.join(out, "3-file-edited.png") });

    // 5. A bad edit: its error (file and place) on the page, the picture kept.
    const good = fs.readFileSync(tree, "utf8");
    save(good.replace('"branching_angle": 55', '"branching_angle": -400'));
    const error = await until("the error on the page", () => page.evaluate(() => document.getElementById("error").textContent));
    check(error.includes("tree.json") && error.includes("branching_angle"), "the page names the bad edit: " + error.split("\n")[0]);
    check(await page.evaluate(() => document.getElementById("picture").naturalWidth === 480), "the last picture stays");
    await page.screenshot({ path: path.join(out, "4-bad-edit.png") });
    save(good);

    // 6. Without the token: refused, from the page and from outside it.
    const fromPage = await page.evaluate(async () => (await fetch("/model")).status);
    check(fromPage === 403, "the page's own fetch without the token is refused (" + fromPage + ")");
    for (const p of ["/", "/model", "/picture.png", "/events"]) {
      const r = await get(origin + p);
      check(r.status === 403, `GET ${p} without the token: ${r.status}`);
    }
    check(pageErrors.length === 0, "no script errors on the page " + JSON.stringify(pageErrors));
  } finally {
    if (browser) await browser.close();
    preview.kill("SIGTERM");
    await exited;
    fs.rmSync(work, { recursive: true, force: true });
  }
}

main().then(() => {
  console.log(failures ? `${failures} checks failed` : "all checks passed");
  process.exit(failures ? 1 : 0);
}, (e) => {
  console.log("FAIL " + (e && e.stack || e));
  process.exit(1);
});
