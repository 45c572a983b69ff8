// Feedback for every click: the button shows pending, then accepted or rejected; the answer is
// written next to it (an answer element) and as a toast, and refusals go to the event log.

import { byId, h } from './dom';

export type Outcome = { ok: true; text: string } | { ok: false; text: string };

export type RejectSink = (text: string) => void;
let rejectSink: RejectSink = () => {};

export function onRejected(sink: RejectSink): void {
  rejectSink = sink;
}

export function toast(text: string, ok: boolean | null): void {
  const box = byId('toasts');
  const el = h('div', { className: `toast ${ok === null ? 'info' : ok ? 'ok' : 'bad'}`, role: 'status' }, text);
  box.prepend(el);
  while (box.children.length > 4) box.lastElementChild?.remove();
  setTimeout(() => el.remove(), ok === false ? 9000 : 4000);
}

/** Shows an outcome in an answer element: "accepted: ..." / "rejected: ...". */
export function showAnswer(el: HTMLElement | null, o: Outcome | { pending: string }): void {
  if (!el) return;
  if ('pending' in o) {
    el.className = 'answer pending';
    el.textContent = `pending: ${o.pending}`;
    return;
  }
  el.className = `answer ${o.ok ? 'ok' : 'bad'}`;
  el.textContent = `${o.ok ? 'accepted' : 'rejected'}: ${o.text}`;
}

/**
 * Runs a click's work with visible feedback. `work` returns the outcome; an exception is a
 * rejection with its message.
 */
export async function act(
  button: HTMLButtonElement | null,
  label: string,
  answerEl: HTMLElement | null,
  work: () => Promise<Outcome>,
): Promise<Outcome> {
  button?.classList.remove('was-ok', 'was-bad');
  button?.classList.add('pending');
  button?.setAttribute('aria-busy', 'true');
  showAnswer(answerEl, { pending: label });
  let outcome: Outcome;
  try {
    outcome = await work();
  } catch (e) {
    outcome = { ok: false, text: e instanceof Error ? e.message : String(e) };
  }
  button?.classList.remove('pending');
  button?.removeAttribute('aria-busy');
  button?.classList.add(outcome.ok ? 'was-ok' : 'was-bad');
  setTimeout(() => button?.classList.remove('was-ok', 'was-bad'), 2500);
  showAnswer(answerEl, outcome);
  toast(`${label}: ${outcome.ok ? 'accepted' : 'rejected'} — ${outcome.text}`, outcome.ok);
  if (!outcome.ok) rejectSink(`${label}: ${outcome.text}`);
  return outcome;
}
