// Opens a report page (`ribbon analyze --report DIR` → DIR/index.html) in headless Chromium with
// the network cut off, and prints what a browser made of it as one JSON object on stdout, for
// tests/report_page.rs to judge: console messages and page errors, every request that was not a
// local file, every picture (inline SVG or <img>) with its size on the page and the share of its
// pixels painted when drawn on a canvas, the numbers of the page's tables, and a screenshot.
//
// Usage: node report_page.mjs PAGE.html USER_DATA_DIR SCREENSHOT.png
//   USER_DATA_DIR an empty directory: Chromium's profile for this run
// Needs: playwright-core on NODE_PATH and Chromium (CHROMIUM, default /usr/bin/chromium).
// Exit status: 0 when the page was opened and measured (the verdict is the test's), 2 on a usage
// error, 1 when the browser could not open it.

import { createRequire } from "node:module";
import { pathToFileURL } from "node:url";

const require = createRequire(import.meta.url);
const { chromium } = require("playwright-core");

/** The flags of the team's headless runs: no GPU, nothing fetched in the background. */
const CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
];
/** Longest wait for the page to load, ms. */
const LOAD_TIMEOUT_MS = 60000;
/** Width of the browser window, px (the page's column is at most 1000 px wide). */
const VIEWPORT = { width: 1100, height: 1500 };

const [pagePath, userDataDir, screenshotPath] = process.argv.slice(2);
if (!pagePath || !userDataDir || !screenshotPath) {
    console.error("usage: node report_page.mjs PAGE.html USER_DATA_DIR SCREENSHOT.png");
    process.exit(2);
}

const result = {
    console: [],
    page_errors: [],
    failed_requests: [],
    external_requests: [],
    pictures: [],
    study: {},
    envelope_rows: [],
    parameter_rows: [],
    warnings: [],
};

const context = await chromium.launchPersistentContext(userDataDir, {
    executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium",
    headless: true,
    args: CHROMIUM_FLAGS,
    offline: true,
    viewport: VIEWPORT,
});
try {
    // Anything but the page's own file is a dependency the page must not have: record, refuse.
    await context.route("**/*", (route) => {
        const url = route.request().url();
        if (url.startsWith("file:") || url.startsWith("data:")) {
            return route.continue();
        }
        result.external_requests.push(url);
        return route.abort();
    });
    const page = await context.newPage();
    page.on("console", (m) => result.console.push({ type: m.type(), text: m.text() }));
    page.on("pageerror", (e) => result.page_errors.push(String(e)));
    page.on("requestfailed", (r) =>
        result.failed_requests.push(`${r.url()}: ${r.failure()?.errorText}`),
    );
    await page.goto(pathToFileURL(pagePath).href, {
        waitUntil: "load",
        timeout: LOAD_TIMEOUT_MS,
    });

    // Every picture: its box on the page and, drawn on a canvas the way an <img> would be, the
    // share of pixels that are not white (a picture that fails to decode rejects instead).
    result.pictures = await page.evaluate(async () => {
        const painted = (src, width, height) =>
            new Promise((resolve) => {
                const image = new Image();
                image.onload = () => {
                    const canvas = document.createElement("canvas");
                    canvas.width = width;
                    canvas.height = height;
                    const g = canvas.getContext("2d");
                    g.fillStyle = "#fff";
                    g.fillRect(0, 0, width, height);
                    g.drawImage(image, 0, 0, width, height);
                    const pixels = g.getImageData(0, 0, width, height).data;
                    let ink = 0;
                    for (let i = 0; i < pixels.length; i += 4) {
                        if (pixels[i] < 250 || pixels[i + 1] < 250 || pixels[i + 2] < 250) {
                            ink += 1;
                        }
                    }
                    resolve({ painted_fraction: ink / (width * height), error: null });
                };
                image.onerror = () => resolve({ painted_fraction: 0, error: "does not decode" });
                image.src = src;
            });
        const out = [];
        for (const svg of document.querySelectorAll("svg")) {
            const box = svg.getBoundingClientRect();
            const figure = svg.closest("figure");
            const text = new XMLSerializer().serializeToString(svg);
            const src = "data:image/svg+xml;charset=utf-8," + encodeURIComponent(text);
            const w = Math.max(1, Math.round(box.width));
            const h = Math.max(1, Math.round(box.height));
            out.push({
                kind: figure ? figure.className : "svg",
                output: figure ? figure.dataset.output : null,
                caption: figure?.querySelector("figcaption")?.textContent ?? null,
                untrusted: figure?.dataset.untrusted === "true",
                width: box.width,
                height: box.height,
                texts: svg.querySelectorAll("text").length,
                ...(await painted(src, w, h)),
            });
        }
        for (const img of document.querySelectorAll("img")) {
            out.push({
                kind: "img",
                output: img.alt,
                width: img.naturalWidth,
                height: img.naturalHeight,
                texts: 0,
                ...(img.complete && img.naturalWidth > 0
                    ? await painted(img.src, img.naturalWidth, img.naturalHeight)
                    : { painted_fraction: 0, error: "not loaded" }),
            });
        }
        return out;
    });

    // The numbers: every cell with a data-key, exactly (data-value) and as shown (its text).
    const tables = await page.evaluate(() => {
        const cells = (row) =>
            Object.fromEntries(
                [...row.querySelectorAll("[data-key]")].map((c) => [
                    c.dataset.key,
                    { value: c.dataset.value ?? null, text: c.textContent },
                ]),
            );
        return {
            study: cells(document.querySelector("#study")),
            envelope_rows: [...document.querySelectorAll("#envelope-table tr[data-output]")].map(
                (r) => ({ output: r.dataset.output, untrusted: r.classList.contains("untrusted"), cells: cells(r) }),
            ),
            parameter_rows: [...document.querySelectorAll("#parameter-table tr[data-parameter]")].map(
                (r) => ({ parameter: r.dataset.parameter, cells: cells(r) }),
            ),
            warnings: [...document.querySelectorAll("#warnings .warning")].map((w) => w.textContent),
            first_section: document.querySelector("body > section")?.id ?? null,
        };
    });
    Object.assign(result, tables);
    await page.screenshot({ path: screenshotPath, fullPage: false });
} finally {
    await context.close();
}
console.log(JSON.stringify(result));
