// The labelling page: browse the model's keyframes, click an appliance's pixel to label it (the
// server turns it into a 3D point with the keyframe's depth, as `sightmap label add --keyframe
// --pixel` does), and rename, retype or remove labels. A read-only server shows, never edits.
'use strict';

const $ = (id) => document.getElementById(id);
const state = {
  status: null,
  sessions: [],
  keyframes: [],
  labels: [],
  keyframe: null,      // the open keyframe's entry
  image: null,         // its decoded image
  seen: [],            // labels drawn on it
  clicked: null,       // [u, v] chosen for the next point
  token: new URLSearchParams(location.search).get('token') ||
         sessionStorage.getItem('sightmap-token') || '',
};

async function api(path, options = {}) {
  const headers = {...(options.headers || {})};
  if (options.body !== undefined) headers['Content-Type'] = 'application/json';
  if (state.token && options.method && options.method !== 'GET') {
    headers['X-Sightmap-Token'] = state.token;
  }
  const response = await fetch(path, {...options, headers});
  let body = null;
  try {
    body = await response.json();
  } catch (error) {
    body = {error: `the server answered ${response.status} without JSON`};
  }
  if (!response.ok) {
    if (response.status === 401) showTokenBox();
    throw new Error(body.error || `HTTP ${response.status}`);
  }
  return body;
}

function say(text, isError) {
  $('message').textContent = text;
  $('message').classList.toggle('error', Boolean(isError));
}

function editable() { return state.status && state.status.editable; }

function showTokenBox() { $('token-box').hidden = false; }

async function loadStatus() {
  state.status = await api('/api/status');
  const banner = $('banner');
  if (!state.status.editable) {
    banner.classList.add('readonly');
    banner.textContent = `Read-only: ${state.status.read_only_reason}. ` +
        'Restart sightmap serve without --read-only, on a model file you can write, to edit.';
  } else {
    banner.textContent = `${state.status.keyframes} keyframes, ${state.status.labels} labels ` +
        'in the model. Open a keyframe and click an appliance to label it.';
  }
  for (const element of document.querySelectorAll('.editing-only')) {
    element.hidden = !state.status.editable;
  }
  if (state.status.editable && state.status.token_required && !state.token) showTokenBox();
  document.body.dataset.editable = String(state.status.editable);
}

function keyframeCaption(keyframe) {
  const session = state.sessions.find((s) => s.id === keyframe.session);
  return `#${keyframe.id} · session ${session ? session.number : '?'} · ` +
         `${keyframe.time_s.toFixed(0)} s`;
}

function thumbButton(keyframeId, withCaption) {
  const button = document.createElement('button');
  button.type = 'button';
  button.className = 'thumb';
  button.dataset.keyframe = String(keyframeId);
  const image = document.createElement('img');
  image.loading = 'lazy';
  image.alt = `keyframe ${keyframeId}`;
  image.src = `/api/keyframes/${keyframeId}/image.jpg?max_side=160`;
  button.append(image);
  if (withCaption) {
    // The session is the list's choice; the keyframe and its time say which one this is.
    const caption = document.createElement('span');
    const keyframe = state.keyframes.find((k) => k.id === keyframeId);
    caption.textContent =
        keyframe ? `#${keyframe.id} · ${keyframe.time_s.toFixed(0)} s` : `#${keyframeId}`;
    button.append(caption);
  }
  button.addEventListener('click', () => openKeyframe(keyframeId));
  return button;
}

function renderThumbs() {
  const chosen = $('session').value;
  const thumbs = $('thumbs');
  thumbs.replaceChildren();
  for (const keyframe of state.keyframes) {
    if (chosen !== 'all' && String(keyframe.session) !== chosen) continue;
    const button = thumbButton(keyframe.id, true);
    if (state.keyframe && state.keyframe.id === keyframe.id) button.classList.add('current');
    thumbs.append(button);
  }
}

async function loadKeyframes() {
  const answer = await api('/api/keyframes');
  state.sessions = answer.sessions;
  state.keyframes = answer.keyframes;
  const select = $('session');
  select.replaceChildren(new Option(`all sessions (${state.keyframes.length})`, 'all'));
  for (const session of state.sessions) {
    select.append(new Option(`session ${session.number} (${session.keyframes})`,
                             String(session.id)));
  }
  renderThumbs();
}

function drawKeyframe() {
  const canvas = $('keyframe');
  const image = state.image;
  if (!image) return;
  canvas.width = image.naturalWidth;
  canvas.height = image.naturalHeight;
  const context = canvas.getContext('2d');
  context.drawImage(image, 0, 0);
  const unit = markUnit(canvas, 7);
  context.font = `600 ${Math.round(unit * 1.7)}px system-ui, sans-serif`;
  context.textBaseline = 'middle';
  for (const label of state.seen) {
    for (const point of label.points) {
      const [u, v] = point.pixel;
      drawMark(context, u, v, unit, {
        lineWidthRatio: 1 / 2.5,
        dashed: point.hidden,
        fill: point.hidden ? 'rgba(255,255,255,0.4)' : '#0a8a4a',
        stroke: point.hidden ? '#7a8494' : '#ffffff',
      });
      const text = label.name + (point.hidden ? ' (behind)' : '');
      const width = context.measureText(text).width;
      const x = Math.min(u + unit * 1.5, canvas.width - width - unit);
      context.fillStyle = 'rgba(0,0,0,0.6)';
      context.fillRect(x - unit * 0.4, v - unit, width + unit * 0.8, unit * 2);
      context.fillStyle = '#ffffff';
      context.fillText(text, x, v);
    }
  }
  if (state.clicked) {
    const [u, v] = state.clicked;
    context.strokeStyle = '#ff2d55';
    context.lineWidth = unit / 3;
    context.beginPath();
    context.moveTo(u - 2 * unit, v);
    context.lineTo(u + 2 * unit, v);
    context.moveTo(u, v - 2 * unit);
    context.lineTo(u, v + 2 * unit);
    context.stroke();
  }
}

async function openKeyframe(id) {
  const keyframe = state.keyframes.find((k) => k.id === id);
  if (!keyframe) return;
  state.keyframe = keyframe;
  state.clicked = null;
  $('add-point').disabled = true;
  $('clicked').textContent = 'No pixel chosen yet.';
  say('');
  $('viewer').hidden = false;
  $('viewer-title').textContent = `Keyframe ${keyframeCaption(keyframe)}`;
  document.body.dataset.keyframe = '';
  for (const thumb of document.querySelectorAll('#thumbs .thumb')) {
    thumb.classList.toggle('current', thumb.dataset.keyframe === String(id));
  }
  const image = new Image();
  const loaded = new Promise((resolve, reject) => {
    image.onload = resolve;
    image.onerror = () => reject(new Error('the keyframe image did not load'));
  });
  image.src = `/api/keyframes/${id}/image.jpg`;
  try {
    const [, seen] = await Promise.all([loaded, api(`/api/keyframes/${id}/labels`)]);
    if (state.keyframe !== keyframe) return;  // another keyframe was opened meanwhile
    state.image = image;
    state.seen = seen.labels;
    drawKeyframe();
    document.body.dataset.keyframe = String(id);
    $('viewer').scrollIntoView({block: 'start'});
  } catch (error) {
    say(error.message, true);
  }
}

function step(direction) {
  if (!state.keyframe) return;
  const index = state.keyframes.findIndex((k) => k.id === state.keyframe.id);
  const next = state.keyframes[index + direction];
  if (next) openKeyframe(next.id);
}

// The image pixel under a click: pixel centres at integer coordinates.
function pixelOf(event) {
  const canvas = $('keyframe');
  const box = canvas.getBoundingClientRect();
  const u = Math.round((event.clientX - box.left) / box.width * canvas.width - 0.5);
  const v = Math.round((event.clientY - box.top) / box.height * canvas.height - 0.5);
  return [Math.min(Math.max(u, 0), canvas.width - 1), Math.min(Math.max(v, 0), canvas.height - 1)];
}

function pickPixel(event) {
  if (!editable() || !state.image) return;
  state.clicked = pixelOf(event);
  $('clicked').textContent = `Pixel ${state.clicked[0]}, ${state.clicked[1]} of keyframe ` +
                             `${state.keyframe.id}.`;
  $('add-point').disabled = false;
  drawKeyframe();
  $('label-name').focus();
}

async function addPoint(event) {
  event.preventDefault();
  if (!state.clicked || !state.keyframe) return;
  const request = {
    name: $('label-name').value.trim(),
    keyframe: state.keyframe.id,
    pixel: state.clicked,
  };
  const type = $('label-type').value.trim();
  if (type) request.type = type;
  try {
    const answer = await api('/api/labels', {method: 'POST', body: JSON.stringify(request)});
    say(answer.message);
    state.clicked = null;
    $('add-point').disabled = true;
    await Promise.all([loadLabels(), openKeyframe(state.keyframe.id)]);
    say(answer.message);
    // Once the list and the keyframe show it (the browser test waits for this).
    document.body.dataset.lastAdded = answer.label.name;
  } catch (error) {
    say(error.message, true);
  }
}

function labelRow(label) {
  const row = document.createElement('tr');
  row.dataset.labelId = String(label.id);
  row.dataset.labelName = label.name;
  const nameCell = document.createElement('td');
  const typeCell = document.createElement('td');
  const actionCell = document.createElement('td');
  if (editable()) {
    const name = Object.assign(document.createElement('input'),
                               {type: 'text', value: label.name, className: 'label-name'});
    const type = Object.assign(document.createElement('input'),
                               {type: 'text', value: label.type, className: 'label-type'});
    type.setAttribute('list', 'label-types');
    name.setAttribute('aria-label', `name of ${label.name}`);
    type.setAttribute('aria-label', `type of ${label.name}`);
    nameCell.append(name);
    typeCell.append(type);
    const save = Object.assign(document.createElement('button'),
                               {type: 'button', textContent: 'Save', className: 'save'});
    save.addEventListener('click', async () => {
      try {
        await api(`/api/labels/${label.id}`, {
          method: 'PATCH',
          body: JSON.stringify({name: name.value.trim(), type: type.value.trim()}),
        });
        say(`Saved '${name.value.trim()}'.`);
        await loadLabels();
      } catch (error) {
        say(error.message, true);
      }
    });
    const remove = Object.assign(document.createElement('button'),
                                 {type: 'button', textContent: 'Remove', className: 'danger remove'});
    remove.addEventListener('click', async () => {
      if (!confirm(`Remove the label '${label.name}' and its ${label.points.length} point(s)?`)) {
        return;
      }
      try {
        await api(`/api/labels/${label.id}`, {method: 'DELETE'});
        say(`Removed '${label.name}'.`);
        await loadLabels();
        if (state.keyframe) await openKeyframe(state.keyframe.id);
      } catch (error) {
        say(error.message, true);
      }
    });
    actionCell.append(save, ' ', remove);
  } else {
    nameCell.textContent = label.name;
    typeCell.textContent = label.type;
  }
  const seen = document.createElement('div');
  seen.className = 'seen';
  const count = document.createElement('span');
  count.className = 'muted';
  count.textContent = `${label.points.length} point(s); seen by ` +
                      (label.seen_by.length ? '' : 'no keyframe');
  seen.append(count);
  for (const id of label.seen_by) seen.append(thumbButton(id, false));
  nameCell.append(seen);
  row.append(nameCell, typeCell, actionCell);
  return row;
}

async function loadLabels() {
  const answer = await api('/api/labels');
  state.labels = answer.labels;
  const body = $('labels');
  body.replaceChildren(...state.labels.map(labelRow));
  $('no-labels').hidden = state.labels.length > 0;
  $('label-names').replaceChildren(...state.labels.map((label) => new Option(label.name)));
}

async function start() {
  try {
    await loadStatus();
    await Promise.all([loadKeyframes(), loadLabels()]);
    document.body.dataset.ready = 'true';
  } catch (error) {
    $('banner').textContent = `The model cannot be read: ${error.message}`;
    $('banner').classList.add('error');
  }
}

$('keyframe').addEventListener('click', pickPixel);
$('add-form').addEventListener('submit', addPoint);
$('session').addEventListener('change', renderThumbs);
$('previous').addEventListener('click', () => step(-1));
$('next').addEventListener('click', () => step(1));
$('token-form').addEventListener('submit', (event) => {
  event.preventDefault();
  state.token = $('token-input').value.trim();
  sessionStorage.setItem('sightmap-token', state.token);
  $('token-box').hidden = true;
});
if (state.token) sessionStorage.setItem('sightmap-token', state.token);
start();
