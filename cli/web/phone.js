// The phone page: a photo goes to POST /locate (downscaled here when it is larger than the
// server needs, with its 35 mm focal length passed on as intrinsics), and the answer is drawn on
// it: each appliance in view at its pixel, nearest first.
'use strict';

const MAX_SIDE_PX = 1280;               // what the server matches at; larger photos are scaled
const MAX_UPLOAD_BYTES = 8 * 1024 * 1024;
const FILM_DIAGONAL_MM = Math.hypot(36, 24);  // the 35 mm equivalent's reference frame
const NO_BUILDING_SYSTEM =
    'No building system is connected to sightmap yet, so these actions cannot be sent.';

// What a building system would offer for an appliance, by words in its type.
const ACTIONS = [
  [['projector', 'screen', 'display', 'monitor', 'tv', 'television'],
   ['Turn on', 'Turn off', 'Switch input']],
  [['light', 'lamp'], ['Turn on', 'Turn off', 'Dim']],
  [['thermostat', 'heater', 'radiator', 'air', 'hvac', 'fan'],
   ['Warmer', 'Cooler', 'Turn off']],
  [['speaker', 'audio'], ['Volume up', 'Volume down', 'Mute']],
  [['printer', 'copier', 'scanner'], ['Show queue', 'Cancel my jobs']],
  [['blind', 'shade', 'curtain'], ['Raise', 'Lower']],
  [['door', 'lock'], ['Unlock', 'Lock']],
];

const $ = (id) => document.getElementById(id);
let applianceIndex = null;  // name -> /appliances entry, fetched on the first tap

function actionsFor(type) {
  const words = (type || '').toLowerCase();
  for (const [keys, actions] of ACTIONS) {
    if (keys.some((key) => words.includes(key))) return actions;
  }
  return ['Turn on', 'Turn off'];
}

// FocalLengthIn35mmFilm (EXIF tag 0xA405) of a JPEG, or null. Only needed when the photo is
// re-encoded here, which drops its EXIF.
function focal35mm(buffer) {
  const view = new DataView(buffer);
  if (view.byteLength < 4 || view.getUint16(0) !== 0xFFD8) return null;
  let offset = 2;
  while (offset + 4 <= view.byteLength) {
    const marker = view.getUint16(offset);
    const length = view.getUint16(offset + 2);
    if (marker === 0xFFE1 && offset + 10 <= view.byteLength &&
        view.getUint32(offset + 4) === 0x45786966) {  // "Exif"
      return focal35mmInTiff(view, offset + 10, length - 8);
    }
    if ((marker & 0xFF00) !== 0xFF00 || marker === 0xFFDA) return null;
    offset += 2 + length;
  }
  return null;
}

function focal35mmInTiff(view, start, size) {
  const end = Math.min(view.byteLength, start + size);
  if (start + 8 > end) return null;
  const little = view.getUint16(start) === 0x4949;
  const u16 = (at) => (at + 2 <= end ? view.getUint16(at, little) : 0);
  const u32 = (at) => (at + 4 <= end ? view.getUint32(at, little) : 0);
  const findTag = (ifd, tag) => {
    const count = u16(start + ifd);
    for (let i = 0; i < count; ++i) {
      const entry = start + ifd + 2 + 12 * i;
      if (u16(entry) === tag) return entry;
    }
    return null;
  };
  const exifPointer = findTag(u32(start + 4), 0x8769);
  if (exifPointer === null) return null;
  const focal = findTag(u32(exifPointer + 8), 0xA405);
  if (focal === null) return null;
  const value = u16(focal + 8);
  return value > 0 ? value : null;
}

// The photo to send: the file itself when the server can take it as it is (the server reads its
// EXIF orientation and focal length), else an upright JPEG of at most MAX_SIDE_PX with the focal
// length passed as intrinsics. Resolves to {body, query, bitmap} where bitmap is upright.
async function preparePhoto(file) {
  const bitmap = await createImageBitmap(file, {imageOrientation: 'from-image'});
  const longer = Math.max(bitmap.width, bitmap.height);
  const sendable = file.type === 'image/jpeg' || file.type === 'image/png';
  if (sendable && longer <= MAX_SIDE_PX && file.size <= MAX_UPLOAD_BYTES) {
    return {body: file, query: '', bitmap};
  }
  const scale = Math.min(1, MAX_SIDE_PX / longer);
  const width = Math.round(bitmap.width * scale);
  const height = Math.round(bitmap.height * scale);
  // A high-quality (area-averaging) resize: a plain bilinear one blurs and aliases the fine
  // detail the matcher needs, and photos that match at full size stop matching.
  let small;
  try {
    small = await createImageBitmap(file, {
      imageOrientation: 'from-image', resizeWidth: width, resizeHeight: height,
      resizeQuality: 'high'});
  } catch (error) {  // a browser without resize options: its best canvas smoothing instead
    small = bitmap;
  }
  const canvas = document.createElement('canvas');
  canvas.width = width;
  canvas.height = height;
  const context = canvas.getContext('2d');
  context.imageSmoothingQuality = 'high';
  context.drawImage(small, 0, 0, width, height);
  if (small === bitmap) small = await createImageBitmap(canvas);
  const body = await new Promise((resolve) => canvas.toBlob(resolve, 'image/jpeg', 0.92));
  let query = '';
  const focal = focal35mm(await file.arrayBuffer());
  if (focal) {
    const f = focal * Math.hypot(width, height) / FILM_DIAGONAL_MM;
    query = `?fx=${f}&fy=${f}&cx=${(width - 1) / 2}&cy=${(height - 1) / 2}`;
  }
  return {body, query, bitmap: small};
}

function visibilityOf(appliance) {
  if (!appliance.visible) return {css: 'hidden', words: 'behind something'};
  if (appliance.visible_share < 0.999) return {css: 'partly', words: 'partly in view'};
  return {css: 'visible', words: 'in view'};
}

function drawAnswer(bitmap, answer) {
  const canvas = $('photo');
  canvas.width = bitmap.width;
  canvas.height = bitmap.height;
  const context = canvas.getContext('2d');
  context.drawImage(bitmap, 0, 0);
  const unit = markUnit(canvas, 11);
  context.font = `600 ${Math.round(unit * 1.2)}px system-ui, sans-serif`;
  context.textBaseline = 'middle';
  const colours = {visible: '#0a8a4a', partly: '#c77700', hidden: '#7a8494'};
  // Markers farthest first, so the nearest are drawn on top.
  const order = answer.appliances.map((appliance, index) => ({appliance, index})).reverse();
  for (const {appliance, index} of order) {
    const [u, v] = appliance.pixel;
    const look = visibilityOf(appliance);
    drawMark(context, u, v, unit, {
      lineWidthRatio: 1 / 3,
      dashed: look.css !== 'visible',
      fill: look.css === 'visible' ? colours.visible : 'rgba(255,255,255,0.6)',
      stroke: look.css === 'visible' ? '#ffffff' : colours[look.css],
    });
    context.fillStyle = look.css === 'visible' ? '#ffffff' : colours[look.css];
    context.textAlign = 'center';
    context.fillText(String(index + 1), u, v);
  }
  // Names of what is in view, nearest first, beside their marker where they overlap nothing
  // already drawn (the list below names every appliance anyway).
  const taken = answer.appliances.map(({pixel: [u, v]}) =>
      ({x: u - unit, y: v - unit, w: 2 * unit, h: 2 * unit}));
  const overlaps = (a, b) => a.x < b.x + b.w && b.x < a.x + a.w && a.y < b.y + b.h && b.y < a.y + a.h;
  context.textAlign = 'left';
  for (const appliance of answer.appliances) {
    if (!appliance.visible) continue;
    const [u, v] = appliance.pixel;
    const w = context.measureText(appliance.name).width + unit * 0.6;
    const h = unit * 1.6;
    const places = [[u + unit * 1.3, v - h / 2], [u - unit * 1.3 - w, v - h / 2],
                    [u - w / 2, v - unit * 1.3 - h], [u - w / 2, v + unit * 1.3]];
    const place = places.map(([x, y]) => ({x, y, w, h})).find((box) =>
        box.x >= 0 && box.y >= 0 && box.x + w <= canvas.width && box.y + h <= canvas.height &&
        !taken.some((other) => overlaps(box, other)));
    if (!place) continue;
    taken.push(place);
    context.fillStyle = 'rgba(0,0,0,0.65)';
    context.fillRect(place.x, place.y, w, h);
    context.fillStyle = '#ffffff';
    context.fillText(appliance.name, place.x + unit * 0.3, place.y + h / 2);
  }
}

// Fills `list` with one button per appliance, each showing its details when tapped; `numbered`
// as the marks on the photo (an ambiguous photo's places have none drawn).
function fillApplianceList(list, appliances, numbered = true) {
  list.replaceChildren();
  appliances.forEach((appliance, index) => {
    const look = visibilityOf(appliance);
    const item = document.createElement('li');
    item.className = look.css;
    item.dataset.name = appliance.name;
    const button = document.createElement('button');
    button.type = 'button';
    const badge = document.createElement('span');
    badge.className = 'badge';
    badge.textContent = String(index + 1);
    const text = document.createElement('span');
    const name = document.createElement('span');
    name.className = 'name';
    name.textContent = appliance.name;
    const meta = document.createElement('span');
    meta.className = 'meta';
    meta.textContent =
        `${appliance.type} · ${appliance.distance_m.toFixed(1)} m · ${look.words}`;
    text.append(name, meta);
    if (numbered) button.append(badge);
    button.append(text);
    button.addEventListener('click', () => showDetails(appliance));
    item.append(button);
    list.append(item);
  });
}

function listAppliances(answer) {
  fillApplianceList($('appliances'), answer.appliances);
}

// An ambiguous photo: the places it may have been taken at, each with what is in view from
// there, so the person can tell which it is (or see that both hold the same kind of appliance).
function listPossiblePlaces(answer) {
  const section = $('possible');
  const places = answer.possible_places || [];
  section.replaceChildren();
  section.hidden = places.length === 0;
  if (places.length === 0) return;
  const intro = document.createElement('p');
  intro.textContent = `It is one of these ${places.length} places:`;
  section.append(intro);
  places.forEach((place, index) => {
    const heading = document.createElement('h3');
    const inView = place.appliances.filter((a) => a.visible).length;
    heading.textContent = `Place ${index + 1}: ` + (inView === 0
        ? 'no labelled appliance in view'
        : `${inView} appliance${inView === 1 ? '' : 's'} in view`);
    const list = document.createElement('ol');
    list.className = 'appliances';
    list.dataset.place = String(index + 1);
    fillApplianceList(list, place.appliances, /*numbered=*/false);
    section.append(heading, list);
  });
}

async function showDetails(appliance) {
  $('details-name').textContent = appliance.name;
  $('details-type').textContent = appliance.type;
  $('details-distance').textContent = `${appliance.distance_m.toFixed(2)} m from you`;
  $('details-visibility').textContent = visibilityOf(appliance).words;
  $('details-points').textContent = '…';
  const actions = $('details-actions');
  actions.replaceChildren();
  for (const action of actionsFor(appliance.type)) {
    const item = document.createElement('li');
    const button = document.createElement('button');
    button.type = 'button';
    button.disabled = true;
    button.title = NO_BUILDING_SYSTEM;
    button.textContent = action;
    item.append(button);
    actions.append(item);
  }
  $('details-actions-why').textContent = NO_BUILDING_SYSTEM;
  $('details').hidden = false;
  $('details').scrollIntoView({behavior: 'smooth', block: 'start'});
  try {
    if (!applianceIndex) {
      const response = await fetch('/appliances');
      const body = await response.json();
      applianceIndex = new Map(body.appliances.map((entry) => [entry.name, entry]));
    }
    const entry = applianceIndex.get(appliance.name);
    $('details-points').textContent = entry
        ? entry.points.map((p) => `(${p.map((c) => c.toFixed(2)).join(', ')})`).join(' ') +
              ' m in the building'
        : 'not in the model any more';
  } catch (error) {
    $('details-points').textContent = 'could not be read from the server';
  }
}

function setStatus(text, isError) {
  $('status').textContent = text;
  $('status').classList.toggle('error', Boolean(isError));
  if (isError) document.body.dataset.state = 'error';
}

async function locate(file) {
  if (!file) return;
  document.body.dataset.state = 'locating';
  $('details').hidden = true;
  applianceIndex = null;  // labels may have changed since the last photo
  let prepared;
  try {
    prepared = await preparePhoto(file);
  } catch (error) {
    setStatus('This file is not a photo the browser can open: take or choose a JPEG or PNG.', true);
    return;
  }
  setStatus(`Locating the photo (${Math.round(prepared.body.size / 1024)} KB)…`);
  // What was sent, for whoever needs to reproduce an answer (the browser test does).
  document.body.dataset.upload =
      `${prepared.bitmap.width}x${prepared.bitmap.height} ${prepared.body.size}${prepared.query}`;
  window.sightmapLastUpload = prepared.body;
  const start = performance.now();
  let answer;
  try {
    const response = await fetch('/locate' + prepared.query, {
      method: 'POST',
      headers: {'Content-Type': prepared.body.type || 'image/jpeg'},
      body: prepared.body,
    });
    answer = await response.json();
    if (!response.ok) {
      setStatus(`The server refused the photo: ${answer.error || response.status}`, true);
      return;
    }
  } catch (error) {
    setStatus('The server cannot be reached: check the Wi-Fi and try again.', true);
    return;
  }
  const seconds = ((performance.now() - start) / 1000).toFixed(2);
  document.body.dataset.roundTripS = seconds;
  $('result').hidden = false;
  drawAnswer(prepared.bitmap, answer);
  listAppliances(answer);
  listPossiblePlaces(answer);
  $('advice').hidden = answer.matched;
  $('technical').hidden = answer.matched;
  if (!answer.matched) {
    $('advice').textContent = answer.advice || 'The photo could not be placed in the building.';
    $('reason').textContent = answer.reason || '';
    const places = (answer.possible_places || []).length;
    if (places > 0) {
      setStatus(`It could be one of ${places} places (${seconds} s): see below.`);
    } else {
      setStatus(`Not matched (${seconds} s).`, true);
    }
  } else if (answer.appliances.length === 0) {
    setStatus(`Placed in the building, but no labelled appliance is in view (${seconds} s).`);
  } else {
    const inView = answer.appliances.filter((a) => a.visible).length;
    setStatus(`${inView} appliance${inView === 1 ? '' : 's'} in view, nearest first ` +
              `(${seconds} s). Tap one for details.`);
  }
  document.body.dataset.state = answer.matched ? 'matched' : 'unmatched';
}

for (const id of ['camera-input', 'photo-input']) {
  $(id).addEventListener('change', (event) => {
    locate(event.target.files[0]);
    event.target.value = '';  // the same photo again fires another change
  });
}
$('details-close').addEventListener('click', () => { $('details').hidden = true; });
