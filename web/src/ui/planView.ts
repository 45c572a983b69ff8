// Plan panel: the mission being edited (items with schema-driven argument fields, the API's
// validation errors beside them), the JSON view/editor, import/export, upload, and coverage.

import { ApiError } from '../lib/api';
import { enuToGeo, type GeoOrigin } from '../lib/geo';
import {
  addGpsWaypoint,
  addPath,
  addWaypoint,
  appendBeforeLanding,
  coverageMissions,
  emptyMission,
  item,
  landItem,
  missionToJson,
  moveItem,
  moveTarget,
  parseMission,
  removeItem,
  replaceItem,
  sortErrors,
  takeoffItem,
  type PlanDefaults,
  type SortedErrors,
} from '../lib/mission';
import { defaultArgs, fieldsOf, formatField, parseField, type FieldSpec } from '../lib/schema';
import type { BehaviorInfo, CoverageAnswer, Mission, MissionItem, Vec2 } from '../lib/types';
import type { App, DroneRef } from './app';
import { byId, h, setOptions } from './dom';
import { act, showAnswer, type Outcome } from './feedback';
import { describeError } from './instance';

const DRAFT_KEY = 'kestrel.draft';

/** The plan being edited before a reload of the page, if any. */
function savedDraft(): Mission {
  const r = parseMission(sessionStorage.getItem(DRAFT_KEY) ?? '', '');
  return 'mission' in r ? r.mission : emptyMission('');
}

export interface CoveragePlan {
  polygon: Vec2[];
  answer: CoverageAnswer | null;
  missions: Record<string, Mission>;
}

export class PlanView {
  draft: Mission = savedDraft();
  errors: SortedErrors | null = null;
  coverage: CoveragePlan | null = null;
  /** Index of the item the control panel sends with INSERT / MODIFY. */
  chosenItem: number | null = null;
  onChange: () => void = () => {};
  /** Set in the geographic view: clicks then add go_to_gps items (when the drone offers it). */
  geoOrigin: GeoOrigin | null = null;
  private behaviorCount = 0;

  private target = h('select', { id: 'plan-target', 'aria-label': 'mission target drone' });
  private height = h('input', { id: 'plan-height', type: 'number', step: '0.5', value: '3', 'aria-label': 'height (m)' });
  private speed = h('input', { id: 'plan-speed', type: 'number', step: '0.1', value: '1', 'aria-label': 'speed (m/s)' });
  private addBehavior = h('select', { id: 'add-behavior', 'aria-label': 'behavior to add' });
  private items = h('ol', { id: 'plan-items', className: 'items' });
  private general = h('div', { id: 'plan-errors', className: 'errors' });
  private answer = h('p', { id: 'plan-answer', className: 'answer' });
  private json = h('textarea', { id: 'mission-json', rows: '12', spellcheck: 'false', 'aria-label': 'mission JSON' });
  private jsonAnswer = h('p', { id: 'json-answer', className: 'answer' });
  private coverageBox = h('section', { id: 'coverage', className: 'coverage', hidden: true });

  constructor(private readonly app: App) {
    const btn = (id: string, text: string, fn: (b: HTMLButtonElement) => void, cls = '') => {
      const b = h('button', { id, className: cls }, text);
      b.addEventListener('click', () => fn(b));
      return b;
    };
    this.target.addEventListener('change', () => {
      this.draft = { ...this.draft, target: this.targetRef()?.drone ?? '' };
      this.changed(false);
    });
    const upload = btn('btn-upload', 'Upload & load', (b) => this.upload(b, false), 'primary');
    const uploadStart = btn('btn-upload-start', 'Upload, load & start', (b) => this.upload(b, true), 'primary');
    const importFile = h('input', { id: 'import-file', type: 'file', accept: '.json,application/json' });
    importFile.addEventListener('change', () => this.importFile(importFile));
    this.renderItems();
    this.json.value = missionToJson(this.draft);
    byId('panel-plan').append(
      h('h2', {}, 'Plan a mission'),
      h('div', { className: 'row' }, h('label', {}, 'Target ', this.target), h('label', {}, 'Height m ', this.height), h('label', {}, 'Speed m/s ', this.speed)),
      h(
        'div',
        { className: 'row' },
        btn('add-takeoff', '+ takeoff', () => this.push(takeoffItem(this.defaults().height_m, this.defaults().speed_mps))),
        btn('add-land', '+ land', () => this.push(landItem(Math.min(0.5, this.defaults().speed_mps)))),
        this.addBehavior,
        btn('add-item', '+ add', () => this.addSelected()),
        btn('plan-clear', 'Clear', () => this.setDraft(emptyMission(this.draft.target))),
      ),
      h('p', { className: 'hint' }, 'Map tools: Waypoint adds a go_to per click (before a final land), Path draws a follow_path (Finish or double-click), Polygon plans a coverage for several drones.'),
      this.items,
      this.general,
      h('div', { className: 'row' }, upload, uploadStart),
      this.answer,
      this.coverageBox,
      h(
        'details',
        { id: 'json-details' },
        h('summary', {}, 'JSON view / editor, import, export'),
        this.json,
        h('div', { className: 'row' }, btn('btn-apply-json', 'Apply JSON', () => this.applyJson()), btn('btn-export', 'Export file', () => this.exportFile()), h('label', { className: 'file' }, 'Import file ', importFile)),
        this.jsonAnswer,
      ),
    );
  }

  defaults(): PlanDefaults {
    const num = (el: HTMLInputElement, d: number) => (Number.isFinite(parseFloat(el.value)) ? parseFloat(el.value) : d);
    return { height_m: num(this.height, 3), speed_mps: num(this.speed, 1) };
  }

  targetRef(): DroneRef | undefined {
    return this.app.ref(this.target.value) ?? this.app.selected();
  }

  private behaviors(): BehaviorInfo[] {
    return this.targetRef()?.inst.behaviors ?? this.app.instances[0]?.behaviors ?? [];
  }

  /** Called when the fleet or behaviors change: refreshes the target and behavior choices. */
  refreshChoices(): void {
    setOptions(this.target, this.app.drones().map((d) => ({ value: d.key, label: d.name })));
    const behaviors = this.behaviors();
    setOptions(this.addBehavior, behaviors.map((b) => ({ value: b.name, label: b.name })));
    if (behaviors.length !== this.behaviorCount) {
      // The argument fields come from the schemas: draw the items again once they are known.
      this.behaviorCount = behaviors.length;
      this.renderItems();
    }
    if (!this.draft.target && this.targetRef()) {
      this.draft = { ...this.draft, target: this.targetRef()?.drone ?? '' };
      this.changed(false);
    }
  }

  setDraft(m: Mission, keepErrors = false): void {
    this.draft = m;
    if (!keepErrors) this.errors = null;
    this.changed(true);
  }

  private push(it: MissionItem): void {
    this.setDraft({ ...this.draft, plan: [...this.draft.plan, it] });
  }

  private addSelected(): void {
    const b = this.behaviors().find((x) => x.name === this.addBehavior.value);
    if (!b) return;
    const d = this.defaults();
    const preferred = { speed: d.speed_mps, height: d.height_m, z: d.height_m };
    const it = item(b.name, defaultArgs(b.args_schema, preferred));
    this.setDraft(b.name === 'land' || b.name === 'rtl' ? { ...this.draft, plan: [...this.draft.plan, it] } : appendBeforeLanding(this.draft, it));
  }

  addWaypoint(p: Vec2): void {
    const o = this.geoOrigin;
    if (o && o.alt_m !== undefined && this.behaviors().some((b) => b.name === 'go_to_gps')) {
      this.setDraft(addGpsWaypoint(this.draft, enuToGeo(o, p[0], p[1]), o.alt_m, this.defaults()));
      return;
    }
    this.setDraft(addWaypoint(this.draft, p, this.defaults()));
  }

  /** A target dragged on the map: its item (and path point) now goes to `p`. */
  moveWaypoint(index: number, sub: number, p: Vec2): void {
    this.setDraft(moveTarget(this.draft, index, sub, p, this.geoOrigin));
  }

  addPath(points: Vec2[]): void {
    this.setDraft(addPath(this.draft, points, this.defaults()));
  }

  private changed(structure: boolean): void {
    sessionStorage.setItem(DRAFT_KEY, JSON.stringify(this.draft));
    if (structure) this.renderItems();
    if (document.activeElement !== this.json) this.json.value = missionToJson(this.draft);
    this.onChange();
  }

  private schemaOf(name: string) {
    return this.behaviors().find((b) => b.name === name)?.args_schema;
  }

  private renderItems(): void {
    const names = this.behaviors().map((b) => b.name);
    this.items.replaceChildren(...this.draft.plan.map((it, i) => this.renderItem(it, i, names)));
    const general = this.errors?.general ?? [];
    this.general.replaceChildren(...general.map((g) => h('p', { className: 'field-error' }, g)));
  }

  private renderItem(it: MissionItem, index: number, names: string[]): HTMLElement {
    const errs = this.errors?.items.get(index);
    const behavior = h('select', { className: 'item-behavior', 'aria-label': `item ${index} behavior` });
    setOptions(behavior, [...new Set([it.behavior, ...names])].map((n) => ({ value: n, label: n })));
    behavior.value = it.behavior;
    behavior.addEventListener('change', () => {
      const d = this.defaults();
      this.setDraft(replaceItem(this.draft, index, item(behavior.value, defaultArgs(this.schemaOf(behavior.value), { speed: d.speed_mps, height: d.height_m, z: d.height_m }))));
    });
    const small = (text: string, title: string, fn: () => void) => {
      const b = h('button', { className: 'small', title }, text);
      b.addEventListener('click', fn);
      return b;
    };
    const methods = this.behaviors().find((b) => b.name === it.behavior)?.methods ?? [];
    const method = h('select', { className: 'item-method', 'aria-label': `item ${index} method`, title: 'method (argument fields follow __call__)' });
    setOptions(method, [...new Set([it.method ?? '__call__', ...methods])].map((m) => ({ value: m, label: m })));
    method.value = it.method ?? '__call__';
    method.addEventListener('change', () => {
      this.draft = replaceItem(this.draft, index, { ...this.draft.plan[index], method: method.value });
      this.changed(false);
    });
    const choose = h('input', { type: 'radio', name: 'chosen-item', title: 'item sent by INSERT / MODIFY' });
    choose.checked = this.chosenItem === index;
    choose.addEventListener('change', () => (this.chosenItem = index));
    const schemaFields = fieldsOf(this.schemaOf(it.behavior));
    const known = new Set(schemaFields.map((f) => f.name));
    const extra: FieldSpec[] = Object.keys(it.args)
      .filter((k) => !known.has(k))
      .map((name) => ({ name, kind: 'json', required: false, nullable: true, description: 'not in the schema', default: undefined, options: [] }));
    const fields = [...schemaFields, ...extra].map((f) => this.renderField(index, f, it.args[f.name], errs?.args.get(f.name) ?? []));
    return h(
      'li',
      { className: `item${errs ? ' has-error' : ''}`, 'data-index': index },
      h(
        'div',
        { className: 'item-head' },
        h('span', { className: 'idx' }, `#${index}`),
        behavior,
        method.options.length > 1 ? method : '',
        h('label', { className: 'choose' }, choose, 'use'),
        small('↑', 'move up', () => this.setDraft(moveItem(this.draft, index, -1))),
        small('↓', 'move down', () => this.setDraft(moveItem(this.draft, index, 1))),
        small('✕', 'remove', () => this.setDraft(removeItem(this.draft, index))),
      ),
      ...(errs?.item ?? []).map((e) => h('p', { className: 'field-error item-error' }, e)),
      h('div', { className: 'fields' }, fields),
    );
  }

  private renderField(index: number, f: FieldSpec, value: unknown, apiErrors: string[]): HTMLElement {
    const id = `arg-${index}-${f.name}`;
    const err = h('span', { className: 'field-error', 'data-error-for': f.name, role: 'alert' }, apiErrors.join('; '));
    let input: HTMLInputElement | HTMLSelectElement;
    if (f.kind === 'enum' || f.kind === 'boolean') {
      input = h('select', { id, 'data-arg': f.name });
      const opts = f.kind === 'boolean' ? ['true', 'false'] : f.options;
      setOptions(input, [{ value: '', label: '(default)' }, ...opts.map((o) => ({ value: o, label: o }))]);
      input.value = formatField(value);
    } else {
      input = h('input', { id, 'data-arg': f.name, value: formatField(value), inputmode: f.kind === 'number' || f.kind === 'integer' ? 'decimal' : null });
    }
    input.addEventListener('change', () => {
      const parsed = parseField(f, input.value);
      if ('error' in parsed) {
        err.textContent = parsed.error;
        return;
      }
      err.textContent = '';
      const args = { ...this.draft.plan[index].args };
      if (parsed.value === undefined) delete args[f.name];
      else args[f.name] = parsed.value;
      this.draft = replaceItem(this.draft, index, { ...this.draft.plan[index], args });
      this.changed(false);
    });
    return h(
      'div',
      { className: `field${apiErrors.length ? ' invalid' : ''}`, 'data-field': f.name },
      h('label', { for: id, title: f.description }, f.name, f.required ? ' *' : ''),
      input,
      err,
    );
  }

  private async upload(button: HTMLButtonElement, start: boolean): Promise<void> {
    const ref = this.targetRef();
    await act(button, start ? 'upload, load & start' : 'upload & load', this.answer, async () => {
      if (!ref) return { ok: false, text: 'no target drone' };
      if (this.draft.plan.length === 0) return { ok: false, text: 'the plan is empty' };
      try {
        const r = await this.app.upload(ref, this.draft);
        this.errors = null;
        this.renderItems();
        const warn = r.warnings.length ? ` (warnings: ${r.warnings.join('; ')})` : '';
        if (!r.outcome.ok) return { ok: false, text: `mission #${r.missionId} stored; ${r.outcome.text}` };
        if (!start) return { ok: true, text: `mission #${r.missionId} loaded on ${ref.name}${warn}` };
        const s = await this.app.action(ref, 'START', { missionId: r.missionId });
        return s.ok ? { ok: true, text: `mission #${r.missionId} started on ${ref.name}${warn}` } : s;
      } catch (e) {
        if (e instanceof ApiError && e.body.details.length) {
          this.errors = sortErrors(e.body.details);
          this.renderItems();
        }
        return { ok: false, text: describeError(e) };
      }
    });
  }

  private applyJson(): void {
    const r = parseMission(this.json.value, this.draft.target);
    if ('error' in r) {
      showAnswer(this.jsonAnswer, { ok: false, text: r.error });
      return;
    }
    this.setDraft(r.mission);
    showAnswer(this.jsonAnswer, { ok: true, text: `${r.mission.plan.length} item(s) applied` });
  }

  private exportFile(): void {
    const blob = new Blob([missionToJson(this.draft)], { type: 'application/json' });
    const a = h('a', { href: URL.createObjectURL(blob), download: `mission-${this.draft.target || 'drone'}.json` });
    document.body.append(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 1000);
    showAnswer(this.jsonAnswer, { ok: true, text: 'exported' });
  }

  private async importFile(input: HTMLInputElement): Promise<void> {
    const file = input.files?.[0];
    if (!file) return;
    const r = parseMission(await file.text(), this.draft.target);
    input.value = '';
    if ('error' in r) {
      showAnswer(this.jsonAnswer, { ok: false, text: `${file.name}: ${r.error}` });
      return;
    }
    this.setDraft(r.mission);
    showAnswer(this.jsonAnswer, { ok: true, text: `${file.name}: ${r.mission.plan.length} item(s) imported` });
  }

  /** A finished polygon: shows the coverage form for the drones of the target's instance. */
  setPolygon(polygon: Vec2[]): void {
    this.coverage = { polygon, answer: null, missions: {} };
    const ref = this.targetRef();
    const drones = this.app.drones().filter((d) => !ref || d.inst === ref.inst);
    const spacing = h('input', { id: 'cov-spacing', type: 'number', step: '0.5', value: '5', 'aria-label': 'street spacing (m)' });
    const angle = h('input', { id: 'cov-angle', type: 'number', placeholder: 'auto', 'aria-label': 'sweep angle (deg)' });
    const height = h('input', { id: 'cov-height', type: 'number', step: '0.5', value: String(this.defaults().height_m), 'aria-label': 'coverage height (m)' });
    const checks = drones.map((d) => {
      const c = h('input', { type: 'checkbox', value: d.drone, 'data-drone': d.name });
      c.checked = true;
      return { d, c };
    });
    const answer = h('p', { className: 'answer', id: 'cov-answer' });
    const summary = h('ul', { id: 'cov-summary' });
    const planBtn = h('button', { id: 'btn-coverage', className: 'primary' }, 'Plan coverage');
    const goBtn = h('button', { id: 'btn-coverage-go', className: 'primary', disabled: true }, 'Upload & start all');
    planBtn.addEventListener('click', () =>
      act(planBtn, 'coverage', answer, async () => {
        const chosen = checks.filter((x) => x.c.checked).map((x) => x.d);
        if (chosen.length === 0 || !ref) return { ok: false, text: 'choose at least one drone' };
        const h_m = parseFloat(height.value);
        try {
          const a = await ref.inst.client.coverage({
            polygon_enu_m: polygon,
            street_spacing_m: parseFloat(spacing.value),
            angle_deg: angle.value.trim() === '' ? null : parseFloat(angle.value),
            drones: chosen.map((d) => d.drone),
            height_m: h_m,
          });
          const missions = coverageMissions(a, { ...this.defaults(), height_m: h_m });
          this.coverage = { polygon, answer: a, missions };
          summary.replaceChildren(
            ...Object.entries(a.lengths_m).map(([drone, len]) => {
              const edit = h('button', { className: 'small' }, 'edit');
              edit.addEventListener('click', () => {
                const d = drones.find((x) => x.drone === drone);
                if (d) this.target.value = d.key;
                if (missions[drone]) this.setDraft(missions[drone]);
              });
              return h('li', { 'data-drone': drone }, `${drone}: ${len.toFixed(1)} m, ${a.per_drone[drone]?.length ?? 0} points `, edit);
            }),
          );
          goBtn.disabled = Object.keys(missions).length === 0;
          this.onChange();
          return { ok: true, text: `angle ${a.angle_deg.toFixed(0)}°, ${Object.keys(missions).length} drone(s)` };
        } catch (e) {
          return { ok: false, text: describeError(e) };
        }
      }),
    );
    goBtn.addEventListener('click', () => act(goBtn, 'coverage upload & start', answer, () => this.flyCoverage(drones)));
    const cancel = h('button', {}, 'Discard polygon');
    cancel.addEventListener('click', () => {
      this.coverage = null;
      this.coverageBox.hidden = true;
      this.onChange();
    });
    this.coverageBox.replaceChildren(
      h('h3', {}, `Coverage of a ${polygon.length}-vertex polygon`),
      h('div', { className: 'row' }, h('label', {}, 'Spacing m ', spacing), h('label', {}, 'Angle ° ', angle), h('label', {}, 'Height m ', height)),
      h('div', { className: 'row', id: 'cov-drones' }, ...checks.map(({ d, c }) => h('label', {}, c, d.name))),
      h('div', { className: 'row' }, planBtn, goBtn, cancel),
      summary,
      answer,
    );
    this.coverageBox.hidden = false;
    this.onChange();
  }

  private async flyCoverage(drones: DroneRef[]): Promise<Outcome> {
    const missions = this.coverage?.missions ?? {};
    const refs = drones.filter((d) => missions[d.drone]);
    return this.app.forAll(refs, async (ref) => {
      try {
        const r = await this.app.upload(ref, missions[ref.drone]);
        if (!r.outcome.ok) return r.outcome;
        return await this.app.action(ref, 'START', { missionId: r.missionId });
      } catch (e) {
        return { ok: false, text: `${ref.name}: ${describeError(e)}` };
      }
    });
  }

  chosen(): MissionItem | null {
    return this.chosenItem === null ? null : (this.draft.plan[this.chosenItem] ?? null);
  }
}
