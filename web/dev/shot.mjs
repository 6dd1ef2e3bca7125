// Development helper: screenshot a dashboard URL with Debian's chromium.
// Usage: node dev/shot.mjs URL OUT.png [width height]
import { createRequire } from 'node:module';
const require = createRequire(import.meta.url);
const { chromium } = require('playwright-core');
const [url, out, w = '1500', hgt = '1900'] = process.argv.slice(2);
const browser = await chromium.launch({ executablePath: '/usr/bin/chromium', args: ['--no-sandbox', '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run', '--enable-unsafe-swiftshader', '--use-angle=swiftshader'] });
const page = await browser.newPage({ viewport: { width: Number(w), height: Number(hgt) } });
page.on('console', (m) => console.log('console:', m.type(), m.text()));
page.on('pageerror', (e) => console.log('pageerror:', e.message));
await page.goto(url);
await page.waitForTimeout(Number(process.env.SHOT_WAIT_MS || 2500));
await page.screenshot({ path: out, fullPage: true });
await browser.close();
