// Opens a ribbon MCAP log in a built Foxglove-family web app (Lichtblick, the open-source
// continuation of Foxglove Studio) in headless Chromium on loopback, with ribbon's own layout,
// saves a screenshot per tab of the layout and asserts what the page can show (docs/mcap.md §8).
//
// Usage: node foxglove_check.mjs APP_DIR LOG.mcap LAYOUT.json OUT_PREFIX SEEK_SECONDS
//   APP_DIR       a directory holding the built web app (its index.html)
//   LAYOUT.json   the layout ribbon attached to the log (scripts/viewers/extract_layout.py)
//   OUT_PREFIX    screenshots go to OUT_PREFIX-TAB.png, one per tab of the layout
//   SEEK_SECONDS  the log time the app is opened at (the 3D panel shows the nominal pose there,
//                 the legends the envelope's values)
// Needs: playwright-core on NODE_PATH (scripts/viewers/foxglove.sh installs it) and Debian's
// chromium at /usr/bin/chromium (or CHROMIUM=path).
// Exit status: 0 when every check passed, 1 when one failed (each failure is printed), 2 on a
// usage error.

import { createReadStream, existsSync, readFileSync, statSync } from "node:fs";
import { createServer } from "node:http";
import { createRequire } from "node:module";
import { extname, join, normalize, resolve } from "node:path";

const require = createRequire(import.meta.url);

/** Longest wait for the page to be drawn after it opened or after a tab change, in ms
 * (RIBBON_VIEWER_TIMEOUT_S overrides it, in seconds). */
const LOAD_TIMEOUT_MS = 1000 * Number(process.env.RIBBON_VIEWER_TIMEOUT_S ?? 300);
/** Pictures in a row that must be identical before the page counts as drawn. */
const STILL_FRAMES = 2;
/** Time between those pictures, in ms. */
const STILL_INTERVAL_MS = 5000;
/** Longest wait for the first plot panel to appear, in ms. */
const PANEL_TIMEOUT_MS = 120000;
/** Alerts the app raises for every ribbon log, and why each is accepted. */
const EXPECTED_ALERTS = [
    {
        message: "High frequency topics detected",
        why: "envelopes are logged at the scene's record rate (100 Hz on the shipped robots), above the app's 60 Hz warning",
    },
];
/** Chromium flags for a closed network (background requests would be refused and retried). */
const CHROMIUM_FLAGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--use-gl=swiftshader",
    "--enable-unsafe-swiftshader",
];

const CONTENT_TYPES = {
    ".html": "text/html",
    ".js": "text/javascript",
    ".mjs": "text/javascript",
    ".css": "text/css",
    ".json": "application/json",
    ".wasm": "application/wasm",
    ".svg": "image/svg+xml",
    ".png": "image/png",
    ".ico": "image/x-icon",
    ".woff2": "font/woff2",
    ".ttf": "font/ttf",
    ".mcap": "application/octet-stream",
};

function usage(message) {
    process.stderr.write(`foxglove_check.mjs: ${message}\n`);
    process.stderr.write(
        "usage: node foxglove_check.mjs APP_DIR LOG.mcap LAYOUT.json OUT_PREFIX SEEK_SECONDS\n",
    );
    process.exit(2);
}

/** Placeholders in the app's index.html that a self-hosted app replaces by its default layout
 * (Lichtblick's, and Foxglove Studio's before it went closed-source). */
const LAYOUT_PLACEHOLDERS = [
    "/*LICHTBLICK_SUITE_DEFAULT_LAYOUT_PLACEHOLDER*/",
    "/*FOXGLOVE_STUDIO_DEFAULT_LAYOUT_PLACEHOLDER*/",
];

/** The app's index.html with `layout` as its default layout, the way a self-hosted app is given
 * one; an error when the page has no placeholder for it. */
function indexWithLayout(appDir, layout) {
    const page = readFileSync(join(appDir, "index.html"), "utf8");
    const placeholder = LAYOUT_PLACEHOLDERS.find((p) => page.includes(p));
    if (placeholder === undefined) {
        usage(`${appDir}/index.html has none of ${LAYOUT_PLACEHOLDERS.join(", ")}: not a supported app`);
    }
    return page.replace(placeholder, JSON.stringify(layout));
}

/** Serves APP_DIR at / (its index.html with the layout), and the log at /log.mcap with byte
 * ranges (the app reads the log in ranges), on 127.0.0.1 only. */
function serve(appDir, logPath, index) {
    const server = createServer((request, response) => {
        const url = new URL(request.url, "http://127.0.0.1");
        let path;
        if (url.pathname === "/log.mcap") {
            path = logPath;
        } else {
            const relative = normalize(decodeURIComponent(url.pathname)).replace(/^(\.\.[/\\])+/, "");
            path = join(appDir, relative);
            if (!path.startsWith(appDir) || !existsSync(path) || statSync(path).isDirectory()) {
                response.writeHead(200, { "Content-Type": "text/html" });
                response.end(index);
                return;
            }
        }
        const size = statSync(path).size;
        const headers = {
            "Content-Type": CONTENT_TYPES[extname(path)] ?? "application/octet-stream",
            "Accept-Ranges": "bytes",
            "Access-Control-Allow-Origin": "*",
        };
        const range = /^bytes=(\d*)-(\d*)$/.exec(request.headers.range ?? "");
        if (range) {
            const start = range[1] === "" ? size - Number(range[2]) : Number(range[1]);
            const end = range[1] === "" || range[2] === "" ? size - 1 : Math.min(Number(range[2]), size - 1);
            if (start > end || start >= size) {
                response.writeHead(416, { "Content-Range": `bytes */${size}` });
                response.end();
                return;
            }
            headers["Content-Range"] = `bytes ${start}-${end}/${size}`;
            headers["Content-Length"] = end - start + 1;
            response.writeHead(206, headers);
            createReadStream(path, { start, end }).pipe(response);
        } else {
            headers["Content-Length"] = size;
            response.writeHead(200, headers);
            createReadStream(path).pipe(response);
        }
    });
    return new Promise((done) => server.listen(0, "127.0.0.1", () => done(server)));
}

/** RFC 3339 text of a log time in seconds since the epoch (ribbon's logs start at 0). */
function rfc3339(seconds) {
    const whole = Math.floor(seconds);
    const nanos = Math.round((seconds - whole) * 1e9);
    const date = new Date(whole * 1000).toISOString().replace(/\.\d{3}Z$/, "");
    return `${date}.${String(nanos).padStart(9, "0")}Z`;
}

/** Waits until a plot legend shows values at the seek time and then the page has drawn the
 * same picture STILL_FRAMES times in a row (the plots fill in block by block while the app reads
 * the log; a still page has read all of it). A timeout is a failure. */
async function waitUntilDrawn(page, failures) {
    const deadline = Date.now() + LOAD_TIMEOUT_MS;
    let still = 0;
    let previous = null;
    while (still < STILL_FRAMES && Date.now() < deadline) {
        await page.waitForTimeout(STILL_INTERVAL_MS);
        // Legend values are the page's only numbers in text (axis ticks are drawn on canvases).
        const hasValues = await page.evaluate(() => /(^|\s)-?[0-9]+\.[0-9]/.test(document.body.innerText));
        const frame = await page.screenshot();
        still = hasValues && previous !== null && frame.equals(previous) ? still + 1 : 0;
        previous = frame;
    }
    if (still < STILL_FRAMES) failures.push(`the page was still changing after ${LOAD_TIMEOUT_MS / 1000} s`);
}

/** Opens the app's Alerts list and fails on any alert but the EXPECTED_ALERTS. */
async function checkAlerts(page, failures) {
    const label = page.getByRole("tab", { name: /^Alerts/ }).first();
    const tabText = await label.innerText();
    const count = Number((/([0-9]+)/.exec(tabText) ?? ["", "0"])[1]);
    await label.click();
    await page.waitForTimeout(1000);
    const text = await page.locator("body").innerText();
    const expected = EXPECTED_ALERTS.filter((alert) => text.includes(alert.message));
    for (const alert of expected) {
        process.stdout.write(`foxglove_check: expected alert "${alert.message}": ${alert.why}\n`);
    }
    if (count > expected.length) {
        failures.push(`${count} alerts, ${count - expected.length} unexpected; the Alerts list reads:\n${text}`);
    }
}

async function main() {
    const [appArg, logArg, layoutArg, outPrefix, seekArg] = process.argv.slice(2);
    if (seekArg === undefined) usage("five arguments expected");
    const appDir = resolve(appArg);
    if (!existsSync(join(appDir, "index.html"))) {
        usage(`${appDir}: no index.html; pass the directory of a built web app`);
    }
    const logPath = resolve(logArg);
    if (!existsSync(logPath)) usage(`${logPath}: no such log`);
    let layout;
    try {
        layout = JSON.parse(readFileSync(layoutArg, "utf8"));
    } catch (error) {
        usage(`${layoutArg}: not a layout JSON file (${error.message})`);
    }
    if (!(LOAD_TIMEOUT_MS > 0)) {
        usage(`RIBBON_VIEWER_TIMEOUT_S: expected seconds > 0, got ${process.env.RIBBON_VIEWER_TIMEOUT_S}`);
    }
    const seek = Number(seekArg);
    if (!Number.isFinite(seek) || seek < 0) usage(`SEEK_SECONDS: expected seconds ≥ 0, got ${seekArg}`);

    const { chromium } = require("playwright-core");
    const server = await serve(appDir, logPath, indexWithLayout(appDir, layout));
    const port = server.address().port;
    const browser = await chromium.launch({
        executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium",
        args: CHROMIUM_FLAGS,
    });
    const failures = [];
    const consoleErrors = [];
    try {
        const page = await browser.newPage({ viewport: { width: 1600, height: 900 } });
        page.on("console", (message) => {
            if (message.type() === "error") consoleErrors.push(message.text());
        });
        const logUrl = `http://127.0.0.1:${port}/log.mcap`;
        const appUrl =
            `http://127.0.0.1:${port}/?ds=remote-file&ds.url=${encodeURIComponent(logUrl)}` +
            `&time=${encodeURIComponent(rfc3339(seek))}`;
        await page.goto(appUrl);
        await page
            .locator("[data-testid='panel-mouseenter-container'], canvas")
            .first()
            .waitFor({ timeout: PANEL_TIMEOUT_MS });
        await waitUntilDrawn(page, failures);
        const html = await page.content();
        const firstTab = Object.entries(layout.configById).find(([id]) => id.startsWith("Tab!"));
        const tabTitles = firstTab ? firstTab[1].tabs.map((tab) => tab.title) : [];
        const plotTitles = Object.entries(layout.configById)
            .filter(([id]) => id.startsWith("Plot!"))
            .map(([, config]) => config.foxglovePanelTitle);
        if (plotTitles.length === 0) failures.push("the layout has no plot panels");
        for (const title of tabTitles) {
            if (!html.includes(title)) failures.push(`tab "${title}" of the layout is not shown`);
        }
        for (const [index, title] of tabTitles.entries()) {
            if (index > 0) {
                await page.locator(`[data-testid='toolbar-tab'][title="${title}"]`).first().click();
                await waitUntilDrawn(page, failures);
            }
            const text = await page.locator("body").innerText();
            const shown = plotTitles.filter((t) => text.includes(t));
            if (shown.length === 0) failures.push(`tab "${title}": no plot title of the layout is shown`);
            const canvases = await page.locator("canvas").count();
            if (canvases < 2) failures.push(`tab "${title}": ${canvases} canvas drawn (3D and plots expected)`);
            const path = `${outPrefix}-${title.replace(/[^A-Za-z0-9]+/g, "-")}.png`;
            await page.screenshot({ path });
            process.stdout.write(`foxglove_check: ${path}: ${shown.join(", ")}\n`);
        }
        await checkAlerts(page, failures);
    } finally {
        await browser.close();
        server.close();
    }
    for (const message of consoleErrors) process.stderr.write(`console error: ${message}\n`);
    for (const failure of failures) process.stderr.write(`foxglove_check: FAILED: ${failure}\n`);
    process.exit(failures.length === 0 ? 0 : 1);
}

main().catch((error) => {
    process.stderr.write(`foxglove_check.mjs: ${error.stack ?? error}\n`);
    process.exit(1);
});
