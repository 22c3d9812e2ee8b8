// What the phone page and the labelling page both draw on an image: round marks sized for the
// screen, whatever the image's resolution, so a mark reads the same on a 4000 px photo shown in a
// 360 px wide phone as on a 640 px keyframe on a laptop.
'use strict';

// Image pixels per `cssPx` CSS pixels of `canvas` as laid out.
function markUnit(canvas, cssPx) {
  return cssPx * canvas.width / (canvas.getBoundingClientRect().width || canvas.width);
}

// A ring of radius `unit` at (u, v): filled, outlined, dashed when `look.dashed`.
function drawMark(context, u, v, unit, look) {
  context.beginPath();
  context.arc(u, v, unit, 0, 2 * Math.PI);
  context.lineWidth = unit * look.lineWidthRatio;
  context.setLineDash(look.dashed ? [unit / 2, unit / 3] : []);
  context.fillStyle = look.fill;
  context.strokeStyle = look.stroke;
  context.fill();
  context.stroke();
  context.setLineDash([]);
}
