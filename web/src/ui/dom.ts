// Tiny DOM helpers: build elements with attributes and children, find required elements.

type Child = Node | string | number | null | undefined | false;
type Attrs = Record<string, string | number | boolean | null | undefined | EventListener>;

export function h<K extends keyof HTMLElementTagNameMap>(
  tag: K,
  attrs: Attrs = {},
  ...children: (Child | Child[])[]
): HTMLElementTagNameMap[K] {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === null || v === undefined || v === false) continue;
    if (k.startsWith('on') && typeof v === 'function') el.addEventListener(k.slice(2), v);
    else if (k === 'className') el.className = String(v);
    else if (k === 'value' && 'value' in el) (el as HTMLInputElement).value = String(v);
    else el.setAttribute(k, v === true ? '' : String(v));
  }
  for (const c of children.flat()) {
    if (c === null || c === undefined || c === false) continue;
    el.append(typeof c === 'string' || typeof c === 'number' ? String(c) : c);
  }
  return el;
}

export function byId<T extends HTMLElement = HTMLElement>(id: string): T {
  const el = document.getElementById(id);
  if (!el) throw new Error(`#${id} missing from index.html`);
  return el as T;
}

export function option(value: string, label: string, selected = false): HTMLOptionElement {
  const o = h('option', { value }, label);
  o.selected = selected;
  return o;
}

export interface OptionItem {
  value: string;
  label: string;
  /** Shown but not choosable, `title` saying why. */
  disabled?: boolean;
  title?: string;
}

/** Replaces a select's options, keeping the chosen value when it still exists (and is choosable). */
export function setOptions(select: HTMLSelectElement, items: OptionItem[]): void {
  const keep = select.value;
  const same =
    select.options.length === items.length &&
    items.every((it, i) => select.options[i].value === it.value && select.options[i].text === it.label && select.options[i].disabled === !!it.disabled);
  if (same) return;
  select.replaceChildren(
    ...items.map((it) => {
      const o = option(it.value, it.label, it.value === keep && !it.disabled);
      o.disabled = !!it.disabled;
      if (it.title) o.title = it.title;
      return o;
    }),
  );
  const choosable = items.filter((it) => !it.disabled);
  if (!choosable.some((it) => it.value === keep) && choosable.length) select.value = choosable[0].value;
}

export const fmt = (v: number | null | undefined, digits = 1): string =>
  typeof v === 'number' && Number.isFinite(v) ? v.toFixed(digits) : '—';
