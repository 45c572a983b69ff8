// Browser tests of the ground station's finishing items, at 1024 x 768 against a real
// `kestrel sim --no-demo --drones 2`: LAND on a landed drone refused with the reason on the page
// and nothing stored; notices never lie over a control; a plan waypoint dragged on the map moves
// its target; the geographic view without a basemap has a labelled lat/lon graticule and a
// lat/lon cursor readout; the timeline fits and its buttons work.

import assert from 'node:assert/strict';
import { after, before, describe, test } from 'node:test';
import { clickMapAt, openBrowser, startKestrel, until } from './harness.mjs';

/**
 * Visible controls whose visible part intersects the visible part of a notice (boxes clipped by
 * every scrolling ancestor: a button scrolled out of its panel is not under anything).
 */
function controlsUnderNotices() {
  const visible = (el) => {
    const b = el.getBoundingClientRect();
    let r = { left: b.left, right: b.right, top: b.top, bottom: b.bottom };
    for (let a = el.parentElement; a; a = a.parentElement) {
      const st = getComputedStyle(a);
      if (st.overflowX === 'visible' && st.overflowY === 'visible') continue;
      const c = a.getBoundingClientRect();
      r = { left: Math.max(r.left, c.left), right: Math.min(r.right, c.right), top: Math.max(r.top, c.top), bottom: Math.min(r.bottom, c.bottom) };
    }
    return r.right > r.left && r.bottom > r.top ? r : null;
  };
  const notices = [...document.querySelectorAll('#toasts .toast')].map(visible).filter(Boolean);
  const controls = [...document.querySelectorAll('button, select, input, textarea, a, [role="tab"], .leaflet-control, .wp-movable')].filter(
    (el) => el.checkVisibility() && visible(el) && !el.closest('#toasts'),
  );
  const hits = [];
  for (const el of controls) {
    const r = visible(el);
    for (const n of notices) {
      if (r.left < n.right && n.left < r.right && r.top < n.bottom && n.top < r.bottom) {
        hits.push(`${el.tagName.toLowerCase()}#${el.id}.${el.className} "${(el.textContent ?? '').trim().slice(0, 20)}"`);
      }
    }
  }
  return { notices: notices.length, controls: controls.length, hits };
}

describe('ground station finishing items at 1024 x 768', { timeout: 400_000 }, () => {
  let kestrel;
  let browser;
  let page;

  before(async () => {
    kestrel = await startKestrel({ drones: 2, speedup: 5 });
    browser = await openBrowser(kestrel.base, { width: 1024, height: 768 });
    page = browser.page;
    await browser.login();
    await page.locator('.card[data-drone="drone_0"][data-link="ok"]').waitFor({ timeout: 20_000 });
    await page.locator('.card[data-drone="drone_1"][data-link="ok"]').waitFor({ timeout: 20_000 });
  });

  after(async () => {
    await browser?.close();
    await kestrel?.stop();
  });

  const tab = (name) => page.locator(`#tabs [data-tab="${name}"]`).click();

  test('LAND on a landed drone: refused, the reason on the page, no mission stored', async () => {
    await page.locator('#drone-select').selectOption({ label: 'drone_0' });
    await page.locator('#btn-land').click();
    const notice = await until(page, () => {
      const t = document.querySelector('#toasts')?.textContent ?? '';
      return /LAND: rejected/.test(t) && t;
    }, null, 10_000);
    assert.match(notice, /drone_0 is on the ground and disarmed: there is nothing to land/);
    await tab('monitor');
    // The event log has it too (the panel redraws at 4 Hz).
    await until(page, () => /on the ground and disarmed/.test(document.querySelector('#panel-monitor')?.textContent ?? ''), null, 5_000);
    const line = await page.locator('#panel-monitor .log .ev.error .text').first().boundingBox();
    assert.ok(line.width >= 250, `the event log's text gets the panel's width at 1024 px (${line.width} px)`);
    const { status, json } = await kestrel.api('GET', '/api/missions?drone=drone_0');
    assert.equal(status, 200);
    assert.deepEqual(json, [], 'the refused LAND left no mission on drone_0');
    await browser.shot('30-land-refused');
  });

  test('notices never lie over a control', async () => {
    await tab('control');
    // Five answers in a row: refusals (no mission loaded) and HOLDs.
    for (const action of ['START', 'NEXT_ITEM', 'RESUME']) await page.locator(`#ctl-buttons [data-action="${action}"]`).click();
    await page.locator('#btn-hold').click();
    await page.locator('#btn-hold-all').click();
    await until(page, () => document.querySelectorAll('#toasts .toast').length >= 4, null, 10_000);
    for (const name of ['control', 'plan', 'fleet', 'timeline', 'logs']) {
      await tab(name);
      const r = await page.evaluate(controlsUnderNotices);
      assert.ok(r.notices >= 1 && r.controls > 20, `${name}: ${r.notices} notices, ${r.controls} controls`);
      assert.deepEqual(r.hits, [], `${name}: controls under a notice`);
    }
    const strip = await page.locator('#toasts').boundingBox();
    assert.ok(strip.y + strip.height <= 768 + 0.5, 'the notice strip is on screen');
    await browser.shot('31-notices');
  });

  test('a plan waypoint dragged on the map moves its target', async () => {
    await tab('plan');
    await page.locator('#plan-clear').click();
    await page.locator('#plan-target').selectOption({ label: 'drone_1' });
    await page.locator('#tool-waypoint').click();
    await clickMapAt(page, 8, 4);
    await page.locator('#map-tools [data-tool="pan"]').click();
    const before = JSON.parse(await page.locator('#mission-json').inputValue());
    const index = before.plan.findIndex((it) => it.behavior === 'go_to');
    assert.ok(index >= 0, JSON.stringify(before));
    assert.deepEqual([before.plan[index].args.x, before.plan[index].args.y].map(Math.round), [8, 4]);

    const to = await page.evaluate(() => window.__kestrel.mapPoint(16, -4));
    const marker = page.locator(`.wp-movable span[data-item="${index}"]`);
    const box = await marker.boundingBox();
    await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
    await page.mouse.down();
    for (let i = 1; i <= 10; i++) {
      await page.mouse.move(box.x + box.width / 2 + ((to.x - box.x - box.width / 2) * i) / 10, box.y + box.height / 2 + ((to.y - box.y - box.height / 2) * i) / 10);
    }
    await page.mouse.up();
    const moved = await until(page, (i) => {
      const m = JSON.parse(document.querySelector('#mission-json').value);
      const a = m.plan[i]?.args;
      return a && Math.abs(a.x - 16) < 0.5 && Math.abs(a.y + 4) < 0.5 ? m : null;
    }, index, 5_000);
    assert.equal(moved.plan.length, before.plan.length, 'dragging moves, it adds nothing');
    assert.equal(moved.plan[index].args.z, before.plan[index].args.z, 'the height is kept');
    await browser.shot('32-waypoint-dragged');
  });

  test('geographic view without a basemap: labelled lat/lon graticule and a lat/lon readout', async () => {
    await page.locator('#btn-geo').click();
    await until(page, () => document.querySelectorAll('.grat-lat').length >= 2 && document.querySelectorAll('.grat-lon').length >= 2, null, 10_000);
    const lats = await page.locator('.grat-lat').allTextContents();
    const lons = await page.locator('.grat-lon').allTextContents();
    for (const l of lats) assert.match(l, /^\d+\.\d+° [NS]$/);
    for (const l of lons) assert.match(l, /^\d+\.\d+° [EW]$/);

    // The pointer on a latitude line reads that latitude.
    const label = page.locator('.grat-lat').nth(1);
    const deg = Number(await label.getAttribute('data-deg'));
    const box = await label.boundingBox();
    await page.mouse.move(box.x + box.width + 40, box.y + box.height + 1);
    const text = await page.locator('#cursor-readout').textContent();
    const m = text.match(/east -?\d+\.\d m, north -?\d+\.\d m · (\d+\.\d{6})° ([NS]), (\d+\.\d{6})° ([EW])/);
    assert.ok(m, text);
    const lat = Number(m[1]) * (m[2] === 'S' ? -1 : 1);
    const step = Math.abs(Number(await page.locator('.grat-lat').nth(1).getAttribute('data-deg')) - Number(await page.locator('.grat-lat').nth(0).getAttribute('data-deg')));
    assert.ok(Math.abs(lat - deg) < step / 5, `readout ${lat} on the ${deg} line (step ${step})`);
    await browser.shot('33-geographic-graticule');

    await page.locator('#btn-geo').click();
    await until(page, () => document.querySelectorAll('.grat-lat').length === 0, null, 5_000);
    const map = await page.locator('#map').boundingBox();
    await page.mouse.move(map.x + map.width / 2, map.y + map.height / 2);
    await page.mouse.move(map.x + map.width / 2 + 5, map.y + map.height / 2 + 5);
    assert.match(await page.locator('#cursor-readout').textContent(), /north -?\d+\.\d m · \d+\.\d{6}° [NS], \d+\.\d{6}° [EW]/, 'the local view reads lat/lon too');
  });

  test('the timeline fits at 1024 x 768: rows readable, no horizontal scroll, buttons clickable', async () => {
    const takeoff = { target: 'drone_1', plan: [{ behavior: 'takeoff', args: { height: 2, speed: 1 } }, { behavior: 'land', args: { speed: 1 } }] };
    const up = await kestrel.api('POST', '/api/missions', takeoff);
    assert.equal(up.status, 201, JSON.stringify(up.json));
    const start = await kestrel.api('POST', '/api/mission_update', { drone_id: 'drone_1', mission_id: up.json.mission_id, item_id: null, action: 2, mission: null });
    assert.equal(start.status, 200, JSON.stringify(start.json));
    await tab('timeline');
    await until(page, () => document.querySelectorAll('#timeline-live rect[data-behavior="land"]').length > 0, null, 120_000);

    const layout = await page.evaluate(() => {
      const panel = document.querySelector('#panel-timeline').getBoundingClientRect();
      const svg = document.querySelector('#timeline-live svg');
      const s = svg.getBoundingClientRect();
      const labels = [...svg.querySelectorAll('text')].map((t) => {
        const r = t.getBoundingClientRect();
        return { text: t.textContent, left: r.left, right: r.right, size: parseFloat(getComputedStyle(t).fontSize) };
      });
      const bars = [...svg.querySelectorAll('rect')].map((r) => r.getBoundingClientRect());
      return {
        pageScroll: document.documentElement.scrollWidth - document.documentElement.clientWidth,
        panel: { left: panel.left, right: panel.right },
        svg: { left: s.left, right: s.right },
        labels,
        barsLeft: Math.min(...bars.map((b) => b.left)),
        rowLabels: labels.filter((l) => !/ s$/.test(l.text)),
      };
    });
    assert.ok(layout.pageScroll <= 0, `no horizontal page scroll (${layout.pageScroll} px)`);
    assert.ok(layout.svg.left >= layout.panel.left && layout.svg.right <= layout.panel.right + 0.5, `timeline inside its panel ${JSON.stringify(layout.svg)} in ${JSON.stringify(layout.panel)}`);
    assert.ok(layout.rowLabels.some((l) => l.text === 'drone_1 takeoff') && layout.rowLabels.some((l) => l.text === 'drone_1 land'), JSON.stringify(layout.rowLabels));
    for (const l of layout.labels) {
      assert.ok(l.size >= 11, `${l.text}: ${l.size}px`);
      assert.ok(l.left >= layout.svg.left && l.right <= layout.svg.right + 0.5, `${l.text} is not cut off`);
    }
    for (const l of layout.rowLabels) assert.ok(l.right <= layout.barsLeft + 0.5, `${l.text} does not run into the bars`);

    for (const id of ['#tl-rows', '#log-drone', '#btn-fetch-log']) await page.locator(id).click({ trial: true, timeout: 5_000 });
    await page.locator('#btn-fetch-log').click();
    await until(page, () => document.querySelectorAll('#timeline-past rect[data-behavior="takeoff"]').length > 0, null, 20_000);
    await page.locator('#tl-rows').selectOption('drone');
    await until(page, () => document.querySelectorAll('#timeline-live .marker').length > 0 || document.querySelectorAll('#timeline-live text').length > 0, null, 5_000);
    for (const id of ['#btn-land', '#btn-land-all', '#btn-hold', '#btn-hold-all', '#btn-geo']) await page.locator(id).click({ trial: true, timeout: 5_000 });
    await browser.shot('34-timeline-1024');
    assert.deepEqual(browser.pageErrors, []);
    assert.deepEqual(browser.blocked, []);
  });
});
