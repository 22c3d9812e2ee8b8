#!/usr/bin/env python3
"""Writes sim/office_scene.json, the default `office` scene embedded in sightmap.

Three rooms of 10 x 8 m (80 m^2) north of a 2.4 m corridor, x east, y north, z up, metres.
Run from the repository root after editing: python3 sim/tools/make_office_scene.py
"""
import json
import math
import random

rng = random.Random(4)  # furniture details (book sizes, notes) are fixed by this seed

H = 2.8   # ceiling height
T = 0.12  # wall thickness
boxes, appliances = [], []


def box(name, c, s, material, yaw=0.0, group=None):
    b = {"name": name, "center": [round(v, 4) for v in c], "size": [round(v, 4) for v in s],
         "material": material}
    if yaw:
        b["yaw_deg"] = yaw
    if group:
        b["group"] = group
    return b


def add(name, c, s, material, yaw=0.0, group=None):
    boxes.append(box(name, c, s, material, yaw, group))


SK_H, SK_D = 0.08, 0.015  # skirting board height and depth


def wall_x(name, x0, x1, y, material, doors=(), faces=(-1, 1), door_opens=1):
    """A wall along x at y, with door gaps (x_start, x_end), lintel above each door, skirting
    boards on the faces in `faces` (-1 = south, +1 = north), a frame round each door and the open
    door leaf turned back against the wall on the `door_opens` side."""
    cuts = [x0] + [v for d in doors for v in d] + [x1]
    for i in range(0, len(cuts), 2):
        a, b = cuts[i], cuts[i + 1]
        add(f"{name}_{i//2}", [(a + b) / 2, y, H / 2], [b - a, T, H], material)
        for f in faces:
            add(f"skirting_{name}_{i//2}_{'n' if f > 0 else 's'}",
                [(a + b) / 2, y + f * (T + SK_D) / 2, SK_H / 2], [b - a, SK_D, SK_H], "skirting")
    for j, (a, b) in enumerate(doors):
        add(f"{name}_lintel{j}", [(a + b) / 2, y, (2.1 + H) / 2], [b - a, T, H - 2.1], material)
        door_frame(f"{name}_door{j}", [(a + b) / 2, y], b - a, "x")
        # The leaf hinged at x = b, swung open through 90 degrees to lie along the wall.
        add(f"{name}_door{j}_leaf", [b + 0.04 + (b - a) / 2, y + door_opens * (T / 2 + 0.1), 1.03],
            [b - a - 0.04, 0.04, 2.04], "door")
        add(f"{name}_door{j}_handle", [b + (b - a) - 0.08, y + door_opens * (T / 2 + 0.15), 1.0],
            [0.12, 0.03, 0.03], "metal")


def wall_y(name, y0, y1, x, material, doors=(), faces=(-1, 1)):
    cuts = [y0] + [v for d in doors for v in d] + [y1]
    for i in range(0, len(cuts), 2):
        a, b = cuts[i], cuts[i + 1]
        add(f"{name}_{i//2}", [x, (a + b) / 2, H / 2], [T, b - a, H], material)
        for f in faces:
            add(f"skirting_{name}_{i//2}_{'e' if f > 0 else 'w'}",
                [x + f * (T + SK_D) / 2, (a + b) / 2, SK_H / 2], [SK_D, b - a, SK_H], "skirting")
    for j, (a, b) in enumerate(doors):
        add(f"{name}_lintel{j}", [x, (a + b) / 2, (2.1 + H) / 2], [T, b - a, H - 2.1], material)
        door_frame(f"{name}_door{j}", [x, (a + b) / 2], b - a, "y")


def door_frame(name, c, width, along):
    """Jambs and head of a door frame (architrave) standing 2 cm proud of both wall faces."""
    fw, fd = 0.06, T + 0.04
    for k, side in enumerate((-1, 1)):
        off = side * (width / 2 + fw / 2 - 0.02)
        if along == "x":
            add(f"{name}_jamb{k}", [c[0] + off, c[1], 1.05], [fw, fd, 2.1], "door_frame")
        else:
            add(f"{name}_jamb{k}", [c[0], c[1] + off, 1.05], [fd, fw, 2.1], "door_frame")
    size = [width + 2 * fw, fd, fw] if along == "x" else [fd, width + 2 * fw, fw]
    add(f"{name}_head", [c[0], c[1], 2.1 + fw / 2 - 0.02], size, "door_frame")


def appliance(name, kind, points, parts):
    appliances.append({"name": name, "type": kind, "points": [[round(v, 4) for v in p] for p in points],
                       "boxes": parts})


# Facing: yaw_deg rotates a box's local axes; wall items are thin along the wall normal.
def poster(name, x, y, z, w, h, texture, normal):
    """A framed poster on a wall; `normal` is 'n','s','e','w' = the direction it faces."""
    d = 0.02
    if normal in "ns":
        off = d / 2 + T / 2
        yy = y + (off if normal == "n" else -off)
        add(name + "_frame", [x, yy, z], [w + 0.06, d, h + 0.06], "frame")
        add(name, [x, yy + (0.006 if normal == "n" else -0.006), z], [w, d, h], texture,
            yaw=0 if normal == "s" else 180)
    else:
        off = d / 2 + T / 2
        xx = x + (off if normal == "e" else -off)
        add(name + "_frame", [xx, y, z], [d, w + 0.06, h + 0.06], "frame")
        add(name, [xx + (0.006 if normal == "e" else -0.006), y, z], [d, w, h], texture,
            yaw=0 if normal == "e" else 180)


def monitor(name, x, y, facing_yaw):
    """A 24" monitor standing on a desk top at z = 0.74, screen facing yaw (deg, 0 = +x)."""
    import math
    fx, fy = math.cos(math.radians(facing_yaw)), math.sin(math.radians(facing_yaw))
    parts = [box(name + "_stand", [x - 0.08 * fx, y - 0.08 * fy, 0.74 + 0.12], [0.05, 0.08, 0.24], "plastic_dark", facing_yaw),
             box(name + "_foot", [x - 0.05 * fx, y - 0.05 * fy, 0.75], [0.2, 0.25, 0.02], "plastic_dark", facing_yaw),
             box(name + "_body", [x, y, 0.74 + 0.38], [0.05, 0.56, 0.34], "plastic_dark", facing_yaw),
             box(name + "_screen", [x + 0.027 * fx, y + 0.027 * fy, 0.74 + 0.385], [0.005, 0.52, 0.3], "screen_desktop", facing_yaw)]
    appliance(name, "monitor", [[x + 0.03 * fx, y + 0.03 * fy, 0.74 + 0.38]], parts)


def desk(name, x, y, sx, sy):
    add(name + "_top", [x, y, 0.72], [sx, sy, 0.04], "wood")
    for i, (dx, dy) in enumerate([(-1, -1), (1, -1), (-1, 1), (1, 1)]):
        add(f"{name}_leg{i}", [x + dx * (sx / 2 - 0.05), y + dy * (sy / 2 - 0.05), 0.35], [0.05, 0.05, 0.7], "metal")


def chair(name, x, y, yaw):
    """An office chair; group = moved together between sessions. Back towards -x of the chair."""
    import math
    bx, by = -math.cos(math.radians(yaw)) * 0.22, -math.sin(math.radians(yaw)) * 0.22
    add(name + "_base", [x, y, 0.06], [0.55, 0.55, 0.06], "plastic_dark", yaw, name)
    add(name + "_pole", [x, y, 0.28], [0.06, 0.06, 0.4], "metal", yaw, name)
    add(name + "_seat", [x, y, 0.5], [0.48, 0.48, 0.08], "fabric_blue", yaw, name)
    add(name + "_back", [x + bx, y + by, 0.82], [0.06, 0.46, 0.52], "fabric_blue", yaw, name)


BOOK_MATERIALS = ["book_red", "book_blue", "book_green", "book_cream", "book_black", "book_ochre"]


def bookshelf(name, x, y, yaw, texture=None, height=1.9, width=0.9):
    """A case 0.35 deep, open (local +x) front with shelf boards and rows of books of varied
    height, width and colour, leaning and gapped as real shelves are; `texture` is unused (kept so
    every shelf call reads the same)."""
    fx, fy = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    lx, ly = -fy, fx  # local +y along the front

    def at(u, v, z):  # local (u forward, v along) -> world
        return [x + u * fx + v * lx, y + u * fy + v * ly, z]

    add(name + "_case", [x, y, height / 2], [0.35, width, height], "wood_dark", yaw)
    rows = max(2, int(round(height / 0.38)))
    pitch = (height - 0.06) / rows
    for r in range(rows):
        z0 = 0.04 + r * pitch
        add(f"{name}_board{r}", at(0.178, 0, z0 - 0.01), [0.01, width - 0.02, 0.025], "wood", yaw)
        v = -width / 2 + 0.04 + rng.uniform(0.0, 0.08)
        g = 0
        while True:
            w = rng.uniform(0.08, 0.2)  # a run of books of one series
            if v + w > width / 2 - 0.04:
                break
            h = min(pitch - 0.04, rng.uniform(0.18, 0.31))
            add(f"{name}_books{r}_{g}", at(0.178 + rng.uniform(0.002, 0.02), v + w / 2, z0 + h / 2),
                [0.012, w, h], rng.choice(BOOK_MATERIALS), yaw)
            v += w + (rng.uniform(0.03, 0.12) if rng.random() < 0.25 else 0.004)
            g += 1


def pinboard(name, x, y, z, w, h, normal):
    """A cork board with notes, a timetable and photos pinned on it, on a wall facing `normal`."""
    nx, ny = {"n": (0, 1), "s": (0, -1), "e": (1, 0), "w": (-1, 0)}[normal]
    along_x = normal in "ns"
    base = T / 2 + 0.012

    def put(part, u, v, sw, sh, d, material):  # u along the wall, v up, d proud of the wall
        cx = x + (u if along_x else 0) + nx * (base + d)
        cy = y + (0 if along_x else u) + ny * (base + d)
        size = [sw, 0.008, sh] if along_x else [0.008, sw, sh]
        add(f"{name}_{part}", [cx, cy, z + v], size, material,
            yaw=(180 if normal in "nw" else 0))
    put("cork", 0, 0, w, h, 0.0, "cork")
    notes = ["note_text", "note_sudoku", "note_notes", "note_yellow", "note_photo", "note_text2"]
    for k in range(int(w * h * 24)):
        sw, sh = rng.uniform(0.12, 0.24), rng.uniform(0.1, 0.3)
        u = rng.uniform(-w / 2 + sw / 2 + 0.03, w / 2 - sw / 2 - 0.03)
        v = rng.uniform(-h / 2 + sh / 2 + 0.03, h / 2 - sh / 2 - 0.03)
        put(f"note{k}", u, v, sw, sh, 0.006 + 0.002 * k, rng.choice(notes))


def radiator(name, x, y, length, normal):
    """A panel radiator under a window: a back panel and vertical convector ribs."""
    ny = 1 if normal == "n" else -1
    yy = y + ny * (T / 2 + 0.05)
    add(name + "_panel", [x, yy, 0.45], [length, 0.06, 0.55], "radiator")
    n = int(length / 0.06)
    for k in range(n):
        add(f"{name}_rib{k}", [x - length / 2 + (k + 0.5) * length / n, yy + ny * 0.035, 0.45],
            [0.025, 0.015, 0.55], "radiator_rib")
    add(name + "_valve", [x + length / 2 + 0.04, yy, 0.25], [0.04, 0.04, 0.1], "metal")


def socket(name, x, y, z, normal):
    """A double socket or a data outlet plate on a wall."""
    if normal in "ns":
        add(name, [x, y + (1 if normal == "n" else -1) * (T / 2 + 0.008), z], [0.15, 0.016, 0.08],
            "switch_plate")
    else:
        add(name, [x + (1 if normal == "e" else -1) * (T / 2 + 0.008), y, z], [0.016, 0.15, 0.08],
            "switch_plate")


def filing_cabinet(name, x, y, yaw, drawers=4, width=0.47, depth=0.62):
    """A steel filing cabinet; local +x faces the room, drawer fronts with handles and labels."""
    fx, fy = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    h = 0.33 * drawers
    add(name + "_body", [x, y, h / 2], [depth, width, h], "cabinet_grey", yaw)
    for k in range(drawers):
        z = 0.33 * k + 0.165
        u = depth / 2 + 0.006
        add(f"{name}_front{k}", [x + u * fx, y + u * fy, z], [0.012, width - 0.03, 0.3], "cabinet_grey", yaw)
        add(f"{name}_handle{k}", [x + (u + 0.015) * fx, y + (u + 0.015) * fy, z + 0.06],
            [0.02, 0.16, 0.025], "metal", yaw)
        add(f"{name}_label{k}", [x + (u + 0.007) * fx, y + (u + 0.007) * fy, z + 0.1],
            [0.004, 0.08, 0.04], "note_text", yaw)


def desk_clutter(name, x, y, z):
    """A mug, a phone, a pen pot, a stack of folders: what stands on a working desk."""
    add(name + "_mug", [x + 0.15, y - 0.3, z + 0.05], [0.08, 0.08, 0.1], rng.choice(["mug_white", "book_red"]))
    add(name + "_phone", [x - 0.1, y + 0.25, z + 0.04], [0.18, 0.2, 0.07], "plastic_dark", 15)
    add(name + "_penpot", [x + 0.1, y + 0.3, z + 0.06], [0.07, 0.07, 0.12], "metal")
    add(name + "_folders", [x - 0.05, y - 0.25, z + 0.06], [0.3, 0.24, 0.12], rng.choice(BOOK_MATERIALS))


def ceiling_light(name, x, y):
    appliance(name, "ceiling_light", [[x, y, H - 0.03]],
              [box(name + "_frame", [x, y, H - 0.015], [0.64, 0.64, 0.03], "metal"),
               box(name + "_panel", [x, y, H - 0.035], [0.6, 0.6, 0.012], "light_panel")])


def switch(name, x, y, normal):
    dx = {"e": 0.07, "w": -0.07}.get(normal, 0.0)
    dy = {"n": 0.07, "s": -0.07}.get(normal, 0.0)
    size = [0.02, 0.08, 0.12] if normal in "ew" else [0.08, 0.02, 0.12]
    appliance(name, "light_switch", [[x + dx, y + dy, 1.2]],
              [box(name, [x + dx, y + dy, 1.2], size, "switch_plate")])


def thermostat(name, x, y, normal):
    dx = {"e": 0.08, "w": -0.08}.get(normal, 0.0)
    dy = {"n": 0.08, "s": -0.08}.get(normal, 0.0)
    size = [0.04, 0.12, 0.12] if normal in "ew" else [0.12, 0.04, 0.12]
    appliance(name, "thermostat", [[x + dx, y + dy, 1.5]],
              [box(name, [x + dx, y + dy, 1.5], size, "thermostat_face", 0 if normal in "ew" else 90)])


# ---- shell ----
X0, X1, YC, Y1 = 0.0, 30.0, 2.4, 10.4
add("floor_corridor", [15, YC / 2, -0.05], [30.2, YC, 0.1], "lino")
add("floor_rooms", [15, (YC + Y1) / 2, -0.05], [30.2, Y1 - YC, 0.1], "carpet")
add("ceiling", [15, Y1 / 2, H + 0.05], [30.2, Y1 + 0.2, 0.1], "ceiling")
wall_x("wall_south", X0, X1, 0.0, "wall_corridor", faces=(1,))
wall_x("wall_rooms_south", X0, X1, YC, "wall_corridor", doors=[(4.0, 5.2), (14.0, 15.2), (24.0, 25.2)])
WINDOWS_X = [2.5, 7.5, 12.5, 17.5, 22.5, 27.5]
WIN_W, WIN_Z0, WIN_Z1 = 1.8, 0.95, 2.25  # opening width, sill and head heights
# The north wall with an opening per window: full height between them, a breast below and a
# lintel above each.
north_cuts = [X0] + [v for x in WINDOWS_X for v in (x - WIN_W / 2, x + WIN_W / 2)] + [X1]
for i in range(0, len(north_cuts), 2):
    a, b = north_cuts[i], north_cuts[i + 1]
    add(f"wall_north_{i//2}", [(a + b) / 2, Y1, H / 2], [b - a, T, H], "wall_white")
add("skirting_wall_north_s", [(X0 + X1) / 2, Y1 - (T + SK_D) / 2, SK_H / 2], [X1 - X0, SK_D, SK_H],
    "skirting")
wall_y("wall_west", 0.0, Y1, X0, "wall_white", faces=(1,))
wall_y("wall_east", 0.0, Y1, X1, "wall_white", faces=(-1,))
wall_y("wall_ab", YC, Y1, 10.0, "wall_white", doors=[(8.2, 9.4)])
wall_y("wall_bc", YC, Y1, 20.0, "wall_white", doors=[(8.2, 9.4)])
# Windows on the north wall: a frame in each opening, and through the glass the street outside,
# far away. The glass itself is not drawn (it is clear); what is seen through it returns no depth
# (the IR pattern does not come back through glass, and the street is beyond the sensor's range),
# and it moves across the image as far things do, not with the wall.
for i, x in enumerate(WINDOWS_X):
    add(f"window_{i}_breast", [x, Y1, WIN_Z0 / 2], [WIN_W, T, WIN_Z0], "wall_white")
    add(f"window_{i}_lintel", [x, Y1, (WIN_Z1 + H) / 2], [WIN_W, T, H - WIN_Z1], "wall_white")
    fw = 0.06  # frame width; it stands in the opening, 6 cm deep
    for k, side in enumerate((-1, 1)):
        add(f"window_{i}_jamb{k}", [x + side * (WIN_W / 2 - fw / 2), Y1, (WIN_Z0 + WIN_Z1) / 2],
            [fw, 0.06, WIN_Z1 - WIN_Z0], "window_frame")
    add(f"window_{i}_head", [x, Y1, WIN_Z1 - fw / 2], [WIN_W, 0.06, fw], "window_frame")
    add(f"window_{i}_bottom", [x, Y1, WIN_Z0 + fw / 2], [WIN_W, 0.06, fw], "window_frame")
    # Two casements side by side under a fanlight: a mullion, a transom, and a handle on each.
    add(f"window_{i}_mullion", [x, Y1, (WIN_Z0 + WIN_Z1) / 2], [0.08, 0.06, WIN_Z1 - WIN_Z0],
        "window_frame")
    add(f"window_{i}_transom", [x, Y1, 1.85], [WIN_W, 0.06, 0.06], "window_frame")
    for k, side in enumerate((-1, 1)):
        add(f"window_{i}_handle{k}", [x + side * 0.08, Y1 - 0.05, 1.45], [0.025, 0.04, 0.14],
            "metal")
    add(f"window_{i}_sill", [x, Y1 - T / 2 - 0.08, 0.93], [1.9, 0.16, 0.04], "wall_white")
    # A black rubber seal round each of the four panes, 1 cm wide, where glass meets frame.
    g = 0.01
    for k, (x0, x1) in enumerate(((x - WIN_W / 2 + fw, x - 0.04), (x + 0.04, x + WIN_W / 2 - fw))):
        for m, (z0, z1) in enumerate(((WIN_Z0 + fw, 1.82), (1.88, WIN_Z1 - fw))):
            pane = f"window_{i}_seal{2 * k + m}"
            for n, zz in enumerate((z0 + g / 2, z1 - g / 2)):
                add(f"{pane}_h{n}", [(x0 + x1) / 2, Y1 - 0.005, zz], [x1 - x0, 0.06, g], "seal")
            for n, xx in enumerate((x0 + g / 2, x1 - g / 2)):
                add(f"{pane}_v{n}", [xx, Y1 - 0.005, (z0 + z1) / 2], [g, 0.06, z1 - z0], "seal")
# Outside: a building across the street 25 m north, and the street. The office is on the first
# floor, 4 m above the street: from inside, the view out is mostly the facade opposite.
# What is seen through glass or on a screen (the facade, the street, the monitors' desktop, the
# TV) has no depth; no poster inside shows the same picture (or another view of the same scene,
# as aero1/aero3 and leuvenA/leuvenB are), since a poster of the view out of the window is a
# twin no real office has: a photo of the window matched room B's poster of the facade, 12 m and
# 145 degrees from the truth.
add("outside_facade", [15, Y1 + 25, 15], [400, 1, 40], "outside_facade")
add("outside_street", [15, Y1 + 12.6, -4.1], [400, 25, 0.2], "outside_street")

# ---- room A: lab (x 0..10) ----
desk("a_desk1", 0.5, 4.4, 0.8, 1.6)
desk("a_desk2", 0.5, 6.6, 0.8, 1.6)
monitor("monitor_1", 0.35, 4.4, 0)
monitor("monitor_2", 0.35, 6.6, 0)
chair("a_chair1", 1.35, 4.4, 180)
chair("a_chair2", 1.35, 6.6, 180)
appliance("desk_lamp_a", "lamp", [[0.45, 5.3, 1.25]],
          [box("desk_lamp_a_base", [0.4, 5.35, 0.76], [0.16, 0.16, 0.03], "metal"),
           box("desk_lamp_a_arm", [0.4, 5.35, 1.0], [0.025, 0.025, 0.45], "metal"),
           box("desk_lamp_a_shade", [0.5, 5.3, 1.22], [0.22, 0.18, 0.14], "lamp_shade_red")])
bookshelf("a_shelf1", 3.0, Y1 - T / 2 - 0.18, -90, "books1")
bookshelf("a_shelf2", 3.95, Y1 - T / 2 - 0.18, -90, "books2")
add("a_cabinet", [9.7, 5.0, 0.5], [0.5, 1.2, 1.0], "wood", 0)
add("a_table", [5.5, 6.0, 0.72], [1.6, 0.9, 0.04], "wood")
add("a_table_leg", [5.5, 6.0, 0.35], [0.1, 0.1, 0.7], "metal")
add("a_plant_pot", [8.8, 9.6, 0.25], [0.4, 0.4, 0.5], "pot")
add("a_plant", [8.8, 9.6, 0.9], [0.6, 0.6, 0.8], "leaves")
poster("a_poster_graf", 9.94 - 0.0, 3.8, 1.55, 1.0, 0.8, "poster_graf", "w")
poster("a_poster_starry", 9.94, 6.8, 1.55, 1.0, 0.8, "poster_starry", "w")
poster("a_poster_books", 6.5, YC, 1.5, 1.2, 0.9, "poster_books", "n")
add("a_whiteboard", [0.06 + T / 2, 8.6, 1.45], [0.02, 1.8, 1.1], "whiteboard")
switch("switch_a", 3.7, YC, "n")
thermostat("thermostat_a", 0.0, 3.2, "e")
ceiling_light("ceiling_light_1", 3.0, 5.0)
ceiling_light("ceiling_light_2", 7.0, 7.8)

add("a_cabinet2", [6.5, YC + T / 2 + 0.3, 0.45], [1.2, 0.5, 0.9], "wood_dark")
add("a_desk3_top", [5.5, 9.9, 0.72], [1.6, 0.8, 0.04], "wood")
add("a_desk3_side", [5.5, 9.9, 0.35], [1.5, 0.7, 0.7], "wood_dark")
chair("a_chair3", 5.5, 9.3, 90)  # pushed in at the desk

# ---- room B: meeting room (x 10..20) ----
add("b_table", [15.0, 6.4, 0.72], [3.0, 1.2, 0.05], "wood")
add("b_table_leg1", [14.0, 6.4, 0.35], [0.12, 0.8, 0.7], "metal")
add("b_table_leg2", [16.0, 6.4, 0.35], [0.12, 0.8, 0.7], "metal")
for i, x in enumerate([14.0, 15.0, 16.0]):
    chair(f"b_chair_s{i}", x, 5.3, 90)
    chair(f"b_chair_n{i}", x, 7.5, -90)
appliance("projector", "projector", [[15.0, 6.4, 2.52]],
          [box("projector_rod", [15.0, 6.4, 2.68], [0.04, 0.04, 0.24], "metal"),
           box("projector_body", [15.0, 6.4, 2.52], [0.32, 0.26, 0.1], "plastic_light"),
           box("projector_lens", [15.0, 6.54, 2.52], [0.07, 0.02, 0.07], "plastic_dark")])
appliance("projection_screen", "screen", [[15.0, Y1 - 0.1, 1.65]],
          [box("screen_case", [15.0, Y1 - T / 2 - 0.05, 2.5], [2.3, 0.1, 0.1], "plastic_light"),
           box("screen_cloth", [15.0, Y1 - T / 2 - 0.03, 1.7], [2.1, 0.01, 1.5], "projection")])
appliance("tv", "tv", [[19.9 - 0.05, 5.0, 1.4]],
          [box("tv_frame", [20 - T / 2 - 0.04, 5.0, 1.4], [0.06, 1.25, 0.74], "plastic_dark"),
           box("tv_screen", [20 - T / 2 - 0.072, 5.0, 1.4], [0.005, 1.17, 0.66], "screen_tv")])
add("b_sideboard", [19.6, 5.0, 0.4], [0.5, 1.8, 0.8], "wood_dark")
bookshelf("b_shelf1", 10.24, 7.2, 0, "books2")
add("b_flipchart", [11.2, 9.8, 0.95], [0.7, 0.05, 1.0], "whiteboard", 0)
add("b_cabinet", [17.5, YC + T / 2 + 0.25, 0.45], [1.6, 0.5, 0.9], "wood")
poster("b_poster_basketball", 10.0, 5.0, 1.55, 1.1, 0.8, "poster_basketball", "e")
poster("b_poster_board", 17.5, YC, 1.5, 1.2, 0.85, "poster_board", "n")
poster("b_poster_fruits", 11.6, YC, 1.5, 0.8, 0.75, "poster_fruits", "n")
switch("switch_b", 13.7, YC, "n")
ceiling_light("ceiling_light_3", 13.0, 5.4)
ceiling_light("ceiling_light_4", 17.0, 7.4)

# ---- room C: office (x 20..30) ----
desk("c_desk1", 29.5, 4.4, 0.8, 1.6)
desk("c_desk2", 29.5, 6.6, 0.8, 1.6)
monitor("monitor_3", 29.65, 4.4, 180)
monitor("monitor_4", 29.65, 6.6, 180)
chair("c_chair1", 28.65, 4.4, 0)
chair("c_chair2", 28.65, 6.6, 0)
add("c_printer_cabinet", [22.0, 3.0, 0.35], [0.7, 0.55, 0.7], "plastic_light")
appliance("printer", "printer", [[22.0, 3.0, 0.9]],
          [box("printer_body", [22.0, 3.0, 0.88], [0.55, 0.48, 0.36], "printer_front"),
           box("printer_tray", [22.0, 3.3, 0.84], [0.4, 0.15, 0.02], "plastic_dark")])
appliance("floor_lamp", "lamp", [[27.0, 9.6, 1.6]],
          [box("floor_lamp_base", [27.0, 9.6, 0.02], [0.35, 0.35, 0.04], "metal"),
           box("floor_lamp_pole", [27.0, 9.6, 0.8], [0.03, 0.03, 1.55], "metal"),
           box("floor_lamp_shade", [27.0, 9.6, 1.6], [0.42, 0.42, 0.32], "lamp_shade")])
add("c_sofa_seat", [23.5, 9.7, 0.22], [2.0, 0.8, 0.44], "fabric_grey")
add("c_sofa_back", [23.5, 10.2, 0.6], [2.0, 0.2, 0.5], "fabric_grey")
add("c_coffee_table", [23.5, 8.5, 0.4], [1.1, 0.6, 0.04], "wood")
add("c_coffee_leg", [23.5, 8.5, 0.2], [0.8, 0.4, 0.38], "wood_dark")
bookshelf("c_shelf1", 20.06 + 0.18, 6.0, 0, "books3")
bookshelf("c_shelf2", 20.06 + 0.18, 6.95, 0, "books1")
add("c_cabinet", [29.0, YC + T / 2 + 0.25, 0.6], [1.4, 0.5, 1.2], "plastic_light")
bookshelf("c_shelf3", 29.76, 9.7, 180, "books2")
poster("c_poster_baboon", 27.0, YC, 1.5, 0.8, 0.8, "poster_baboon", "n")
poster("c_poster_home", 20.0, 4.0, 1.55, 1.0, 0.75, "poster_home", "e")
poster("c_poster_butterfly", 30.0, 8.6, 1.55, 0.9, 0.65, "poster_butterfly", "w")
switch("switch_c", 25.7, YC, "n")
ceiling_light("ceiling_light_5", 23.0, 5.0)
ceiling_light("ceiling_light_6", 27.0, 7.8)

# ---- corridor ----
poster("k_poster_messi", 3.0, 0.0, 1.5, 1.1, 0.7, "poster_messi", "n")
poster("k_poster_fish", 9.0, 0.0, 1.5, 0.8, 0.6, "poster_fish", "n")
poster("k_poster_smarties", 15.5, 0.0, 1.5, 0.8, 0.7, "poster_smarties", "n")
poster("k_poster_whale", 21.0, 0.0, 1.5, 1.0, 0.66, "poster_whale", "n")
poster("k_poster_graf3", 27.0, 0.0, 1.5, 1.0, 0.8, "poster_graf3", "n")
poster("k_notice_board", 12.0, 0.0, 1.45, 1.2, 0.9, "notice_board", "n")
add("k_bench", [6.5, 0.35, 0.42], [1.6, 0.45, 0.04], "wood_dark")
add("k_bench_leg0", [5.8, 0.35, 0.2], [0.06, 0.4, 0.4], "metal")
add("k_bench_leg1", [7.2, 0.35, 0.2], [0.06, 0.4, 0.4], "metal")
add("k_bench_rail", [6.5, 0.35, 0.1], [1.4, 0.05, 0.04], "metal")
add("k_bench_bag", [6.9, 0.33, 0.59], [0.32, 0.2, 0.3], "fabric_grey")
add("k_bench_papers", [6.1, 0.35, 0.445], [0.3, 0.22, 0.01], "papers")
thermostat("thermostat_corridor", 18.5, 0.0, "n")

# ---- more wall decoration and desk clutter: offices are busy ----
extra_posters = [
    ("a_poster_s1", 1.8, YC, 1.55, 0.9, 0.7, "poster_aloe", "n"),
    ("a_poster_s2", 8.8, YC, 1.55, 0.8, 0.8, "poster_apple", "n"),
    ("a_poster_w1", 0.0, 5.5, 1.8, 0.7, 0.5, "poster_suzanne", "e"),
    ("a_poster_n1", 5.5, Y1, 1.65, 1.0, 0.7, "poster_squirrel", "s"),
    ("b_poster_s1", 19.2, YC, 1.55, 0.7, 0.9, "poster_orange", "n"),
    ("b_poster_w1", 10.0, 3.4, 1.55, 0.9, 0.7, "poster_blox", "e"),
    ("b_poster_e1", 20.0, 3.3, 1.55, 0.9, 0.7, "poster_cards", "w"),
    ("b_poster_e2", 20.0, 7.0, 1.55, 0.9, 0.7, "poster_plate", "w"),
    ("c_poster_n1", 25.0, Y1, 1.6, 1.1, 0.8, "poster_sudoku", "s"),
    ("c_poster_e1", 30.0, 5.5, 1.85, 0.8, 0.5, "poster_linux", "w"),
    ("c_poster_s1", 23.2, YC, 1.6, 0.8, 0.6, "poster_pic5", "n"),
    ("k_poster_n1", 1.5, YC, 1.5, 0.9, 0.7, "poster_starry", "s"),
    ("k_poster_n2", 8.0, YC, 1.5, 1.0, 0.75, "poster_pic1", "s"),
    ("k_poster_n3", 11.2, YC, 1.5, 0.8, 0.8, "poster_suzanne", "s"),
    ("k_poster_n4", 18.0, YC, 1.5, 1.1, 0.8, "poster_aloe", "s"),
    ("k_poster_n5", 21.3, YC, 1.5, 0.9, 0.7, "poster_orange", "s"),
    ("k_poster_n6", 28.0, YC, 1.5, 1.0, 0.75, "poster_blox", "s"),
]
# The corridor: a notice or picture every ~2.5 m on both walls, as corridors have.
corridor_textures = ["poster_graf", "poster_books", "poster_fruits", "poster_home", "poster_butterfly",
                     "poster_cards", "poster_sudoku", "poster_plate", "poster_pic5", "poster_squirrel",
                     "poster_apple", "poster_baboon"]
# Every other one a printed notice (text, a timetable) rather than a picture.
notices = ["notice_text", "notice_sudoku", "notice_text2"]
for i, x in enumerate([0.8, 5.9, 13.4, 16.5, 19.8, 23.2, 25.6, 29.2]):
    tex = corridor_textures[i % 12] if i % 2 else notices[(i // 2) % 3]
    extra_posters.append((f"k_notice_s{i}", x, 0.0, 1.45, 0.7, 0.9, tex, "n"))
for i, x in enumerate([3.0, 6.6, 9.8, 12.8, 16.3, 20.1, 26.6]):
    tex = corridor_textures[(i + 5) % 12] if i % 2 else notices[(i // 2) % 3]
    extra_posters.append((f"k_notice_n{i}", x, YC, 1.45, 0.7, 0.9, tex, "s"))
for args in extra_posters:
    poster(*args)
for name, x, y, sign in [("a_desk1", 0.5, 4.4, 1), ("a_desk2", 0.5, 6.6, 1),
                         ("c_desk1", 29.5, 4.4, -1), ("c_desk2", 29.5, 6.6, -1)]:
    add(name + "_keyboard", [x + sign * 0.2, y, 0.755], [0.16, 0.45, 0.03], "plastic_dark")
    add(name + "_books", [x, y + 0.6, 0.84], [0.25, 0.3, 0.2], "books2")
    add(name + "_papers", [x + sign * 0.1, y - 0.55, 0.745], [0.3, 0.22, 0.01], "papers")
    add(name + "_drawers", [x, y - 0.45, 0.35], [0.6, 0.45, 0.65], "plastic_light")

# Tall things people stand behind: plants and a desk partition.
add("a_plant_tall_pot", [1.6, 5.5, 0.2], [0.4, 0.4, 0.4], "pot")
add("a_plant_tall", [1.6, 5.5, 1.1], [0.6, 0.6, 1.4], "leaves")
add("b_plant_tall_pot", [18.8, 3.2, 0.2], [0.4, 0.4, 0.4], "pot")
add("b_plant_tall", [18.8, 3.2, 1.1], [0.6, 0.6, 1.4], "leaves")
add("c_partition", [28.9, 5.5, 0.8], [0.8, 0.05, 1.5], "fabric_grey")


# ---- fittings and furniture a working office has (added after the first measurements: bare
# walls and rooms seen end to end gave too few features and too much beyond the sensor's range) ----
TOUR = [[2.0, 1.2], [4.6, 1.3], [4.6, 3.2], [3.2, 4.2], [2.4, 6.2], [3.2, 8.5], [5.5, 8.7],
        [7.8, 7.8], [8.4, 5.5], [7.6, 3.8], [6.8, 4.6], [7.4, 7.2], [8.8, 8.8], [10.0, 8.8],
        [11.4, 8.4], [12.0, 6.0], [12.3, 4.2], [14.6, 3.7], [17.4, 4.0], [18.3, 6.4],
        [18.2, 8.6], [20.0, 8.8], [21.6, 8.4], [21.6, 6.2], [22.6, 4.3], [25.0, 3.8],
        [27.3, 4.2], [27.3, 6.8], [25.8, 8.0], [24.6, 6.5], [24.6, 3.6], [24.6, 1.3],
        [19.0, 1.2], [14.0, 1.1], [8.0, 1.2]]


def clear_of_tour(first_box, margin=0.45):
    """Every box added since `first_box` keeps `margin` metres from the walk (floor plan)."""
    for b in boxes[first_box:]:
        r = 0.5 * math.hypot(b["size"][0], b["size"][1])
        for i in range(len(TOUR)):
            (ax, ay), (bx, by) = TOUR[i], TOUR[(i + 1) % len(TOUR)]
            dx, dy = bx - ax, by - ay
            t = max(0.0, min(1.0, ((b["center"][0] - ax) * dx + (b["center"][1] - ay) * dy) / (dx * dx + dy * dy)))
            d = math.hypot(ax + t * dx - b["center"][0], ay + t * dy - b["center"][1])
            assert d > r + margin, f"{b['name']} is {d - r:.2f} m from the walk"


first = len(boxes)
W_IN = T / 2  # wall face offset from the wall's centre line
# Radiators under the windows that have nothing in front of them.
radiator("a_radiator1", 7.5, Y1, 1.6, "s")
radiator("a_radiator0", 2.0, Y1, 0.7, "s")
radiator("b_radiator0", 12.5, Y1, 1.6, "s")
radiator("b_radiator1", 17.5, Y1, 1.6, "s")
radiator("c_radiator1", 28.0, Y1, 0.8, "s")
# Pinboards with notes.
pinboard("a_pinboard", 9.3, Y1, 1.5, 0.9, 0.7, "s")
pinboard("b_pinboard", 16.2, YC, 1.45, 0.8, 0.6, "n")
pinboard("c_pinboard", 20.0, 4.95, 1.5, 0.7, 0.6, "e")
pinboard("k_pinboard0", 7.2, 0.0, 1.45, 1.0, 0.7, "n")
pinboard("k_pinboard1", 23.0, YC, 1.5, 0.9, 0.6, "s")
# Shelves and cabinets along the walls.
bookshelf("a_shelf3", 1.0, Y1 - T / 2 - 0.18, -90)
filing_cabinet("a_filing1", 10 - W_IN - 0.32, 2.95, 180, drawers=3)
filing_cabinet("a_filing2", 10 - W_IN - 0.32, 3.45, 180, drawers=3)
bookshelf("a_shelf_low", 5.3, 4.6, -90, height=1.1, width=1.2)
bookshelf("b_shelf2", 10 + W_IN + 0.18, 6.2, 0)
filing_cabinet("c_filing1", 26.4, YC + W_IN + 0.32, 90, drawers=3)
filing_cabinet("c_filing2", 26.9, YC + W_IN + 0.32, 90, drawers=3)
# An island of two desks with a screen between them in the office.
add("c_island_top", [26.0, 5.5, 0.72], [1.2, 1.0, 0.04], "wood")
add("c_island_panel", [26.0, 5.5, 0.36], [1.1, 0.04, 0.68], "wood_dark")
add("c_island_screen", [26.0, 5.5, 1.05], [1.2, 0.04, 0.62], "fabric_grey")
desk_clutter("c_island_s", 26.0, 5.2, 0.74)
add("c_island_laptop", [25.8, 5.75, 0.755], [0.34, 0.24, 0.02], "plastic_dark")
# Things on the desks.
for name, x, y in [("a_desk1", 0.5, 4.4), ("a_desk2", 0.5, 6.6), ("c_desk1", 29.5, 4.4),
                   ("c_desk2", 29.5, 6.6)]:
    desk_clutter(name, x, y, 0.74)
desk_clutter("a_desk3", 5.5, 9.9, 0.74)
desk_clutter("a_table", 5.5, 6.0, 0.74)
# Sockets by the floor and the desks.
for i, (x, y, n) in enumerate([(2.0, YC, "n"), (7.0, YC, "n"), (12.0, YC, "n"), (18.0, YC, "n"),
                               (22.0, YC, "n"), (28.0, YC, "n"), (0.0, 5.5, "e"), (30.0, 5.5, "w"),
                               (10.0, 4.5, "w"), (10.0, 4.5, "e"), (20.0, 6.0, "e"), (20.0, 5.2, "w"),
                               (4.0, 0.0, "n"), (11.0, 0.0, "n"), (17.0, 0.0, "n"), (26.0, 0.0, "n")]):
    socket(f"socket_{i}", x, y, 0.3, n)
# The corridor: a fire extinguisher, a coat rack, a water cooler, a recycling bin.
add("k_extinguisher", [14.6, 0.13, 0.45], [0.16, 0.16, 0.55], "book_red")
add("k_extinguisher_sign", [14.6, 0.07, 1.1], [0.2, 0.01, 0.2], "note_yellow")
add("k_coat_rack", [1.0, 0.3, 0.9], [0.5, 0.06, 1.8], "metal")
add("k_coats", [1.0, 0.3, 1.35], [0.45, 0.25, 0.7], "fabric_blue")
add("k_water_cooler", [21.8, 0.25, 0.55], [0.3, 0.3, 1.1], "plastic_light")
add("k_water_bottle", [21.8, 0.25, 1.25], [0.26, 0.26, 0.3], "book_blue")
add("k_bins", [16.9, 0.25, 0.35], [0.7, 0.35, 0.7], "cabinet_grey")
add("k_bins_labels", [16.9, 0.07, 0.55], [0.6, 0.01, 0.1], "note_text")
# Closed doors to the stairs and the store rooms on the corridor's south side.
for i, x in enumerate([10.4, 24.45]):
    door_frame(f"k_door{i}", [x, 0.0], 0.9, "x")
    add(f"k_door{i}_leaf", [x, T / 2 + 0.01, 1.03], [0.9, 0.02, 2.04], "door")
    add(f"k_door{i}_handle", [x + 0.35, T / 2 + 0.05, 1.0], [0.12, 0.04, 0.03], "metal")
    add(f"k_door{i}_sign", [x, T / 2 + 0.025, 1.6], [0.3, 0.01, 0.15], "note_text")
bookshelf("c_shelf4", 20.75, YC + W_IN + 0.18, 90)
bookshelf("a_shelf4", 7.8, YC + W_IN + 0.18, 90)
add("c_clock", [21.2, YC + W_IN + 0.02, 2.2], [0.3, 0.03, 0.3], "note_notes")
add("a_clock", [0.0 + W_IN + 0.02, 7.5, 2.1], [0.03, 0.3, 0.3], "note_notes")
add("a_calendar", [0.0 + W_IN + 0.01, 7.3, 1.5], [0.01, 0.35, 0.5], "notice_sudoku")
# Drawer fronts with handles on the desk pedestals.
for name, x, y, sign in [("a_desk1", 0.5, 4.4, 1), ("a_desk2", 0.5, 6.6, 1),
                         ("c_desk1", 29.5, 4.4, -1), ("c_desk2", 29.5, 6.6, -1)]:
    for k, z in enumerate([0.14, 0.36, 0.56]):
        add(f"{name}_drawer{k}", [x + sign * 0.306, y - 0.45, z], [0.012, 0.41, 0.18], "plastic_light")
        add(f"{name}_drawer{k}_handle", [x + sign * 0.32, y - 0.45, z + 0.05], [0.02, 0.14, 0.02], "metal")
for k, z in enumerate([0.14, 0.36, 0.56]):
    add(f"a_desk3_drawer{k}", [6.0, 9.544, z], [0.42, 0.012, 0.18], "wood")
    add(f"a_desk3_drawer{k}_handle", [6.0, 9.53, z + 0.05], [0.14, 0.02, 0.02], "metal")
add("a_desk3_bin", [4.95, 9.45, 0.17], [0.25, 0.25, 0.34], "cabinet_grey")
# The meeting room's sideboard: cupboard doors and what a meeting needs on top.
for k, y in enumerate([4.4, 5.0, 5.6]):
    add(f"b_sideboard_door{k}", [19.344, y, 0.42], [0.012, 0.56, 0.7], "wood")
    add(f"b_sideboard_knob{k}", [19.33, y + 0.2, 0.6], [0.03, 0.03, 0.03], "metal")
add("b_coffee_machine", [19.6, 4.45, 0.98], [0.3, 0.25, 0.36], "plastic_dark")
add("b_coffee_panel", [19.44, 4.45, 1.05], [0.01, 0.18, 0.1], "note_notes")
add("b_jug", [19.6, 4.95, 0.92], [0.12, 0.12, 0.24], "metal")
add("b_cups", [19.6, 5.25, 0.85], [0.25, 0.18, 0.1], "mug_white")
add("b_folders", [19.6, 5.65, 0.9], [0.3, 0.3, 0.2], "book_blue")
# Staff lockers in the corridor: steel doors with vents, handles and name cards.
LX, LW, LD = 4.95, 0.8, 0.38
add("k_lockers_body", [LX, W_IN + LD / 2, 0.9], [LW, LD, 1.8], "cabinet_grey")
for k in range(4):
    x = LX - LW / 2 + (k + 0.5) * LW / 4
    y = W_IN + LD + 0.006
    add(f"k_locker{k}_door", [x, y, 0.92], [LW / 4 - 0.02, 0.012, 1.7], "locker")
    for v in range(3):
        add(f"k_locker{k}_vent{v}", [x, y + 0.007, 1.55 + 0.05 * v], [0.12, 0.004, 0.015], "plastic_dark")
    add(f"k_locker{k}_handle", [x + 0.07, y + 0.02, 1.0], [0.03, 0.03, 0.1], "metal")
    add(f"k_locker{k}_card", [x, y + 0.008, 1.3], [0.1, 0.004, 0.06], "note_text")
# By the lab door: the escape plan, a fire alarm call point and a hand sanitiser.
poster("k_escape_plan", 8.98, YC, 1.5, 0.62, 0.44, "notice_sudoku", "s")
add("k_call_point", [3.62, YC - W_IN - 0.03, 1.4], [0.1, 0.05, 0.1], "book_red")
add("k_sanitiser", [3.62, YC - W_IN - 0.05, 1.05], [0.12, 0.1, 0.22], "plastic_light")
add("k_sanitiser_label", [3.62, YC - W_IN - 0.101, 1.08], [0.08, 0.002, 0.08], "note_text")
clear_of_tour(first)

# ---- ceilings as real office ceilings are: on the tile grid, supply-air diffusers, sprinkler
# heads and smoke detectors (a photo of a ceiling light shows them, not a bare plane) ----
def ceiling_fixtures(prefix, vents, sprinklers, detectors):
    for i, (x, y) in enumerate(vents):
        add(f"{prefix}_vent{i}", [x, y, H - 0.012], [0.6, 0.6, 0.024], "vent")
    for i, (x, y) in enumerate(sprinklers):
        add(f"{prefix}_sprinkler{i}", [x, y, H - 0.025], [0.045, 0.045, 0.05], "sprinkler")
    for i, (x, y) in enumerate(detectors):
        add(f"{prefix}_smoke_detector{i}", [x, y, H - 0.022], [0.13, 0.13, 0.044], "smoke_detector")


for prefix, ox in (("a", 0.0), ("b", 10.0), ("c", 20.0)):
    ceiling_fixtures(f"{prefix}_ceiling",
                     vents=[(ox + 5.0, 4.2), (ox + 5.0, 8.9)],
                     sprinklers=[(ox + 2.0, 3.5), (ox + 5.0, 6.4), (ox + 8.0, 3.5), (ox + 2.0, 9.0),
                                 (ox + 8.0, 9.2)],
                     detectors=[(ox + 5.6, 5.6)])
ceiling_fixtures("k_ceiling", vents=[(12.0, 1.2), (18.0, 1.2)],
                 sprinklers=[(1.5 + 3.0 * k, 1.2) for k in range(10)],
                 detectors=[(7.5, 1.0), (22.5, 1.0)])

scene = {
    "name": "office",
    "description": "Three 10 x 8 m rooms (lab, meeting room, office) north of a 30 m corridor; "
                   "x east, y north, z up, metres.",
    "ceiling_height_m": H,
    "textures": {
        "graf": "graf1.png", "graf3": "graf3.png", "starry": "starry_night.jpg", "leuven": "leuvenA.jpg",
        "books": "left.jpg", "basketball": "basketball1.png", "building": "building.jpg", "fruits": "fruits.jpg", "baboon": "baboon.jpg",
        "home": "home.jpg", "butterfly": "butterfly.jpg", "messi": "messi5.jpg", "fish": "HappyFish.jpg",
        "smarties": "smarties.png", "whale": "rubberwhale1.png", "box_scene": "box_in_scene.png",
        "stuff": "stuff.jpg", "board": "board.jpg", "leuvenB": "leuvenB.jpg", "notes": "notes.png",
        "pic3": "pic3.png", "aero3": "aero3.jpg", "ela": "ela_original.jpg", "text": "text_defocus.jpg",
        "aloe": "aloeL.jpg", "apple": "apple.jpg", "orange": "orange.jpg", "squirrel": "squirrel_cls.jpg",
        "suzanne": "Blender_Suzanne1.jpg", "blox": "blox.jpg", "cards": "cards.png", "sudoku": "sudoku.png",
        "linux": "LinuxLogo.jpg", "plate": "licenseplate_motion.jpg", "pic1": "pic1.png", "pic5": "pic5.png",
        "box": "box.png", "textN": "imageTextN.png", "chicky": "chicky_512.png",
        # Drawn by sightmap (sim/scene.h): one 600 mm tile of the suspended ceiling's grid, the
        # same on every tile as real grids are, and a diffuser's louvres.
        "ceiling_tile": "procedural:ceiling_tile", "vent": "procedural:vent",
    },
    "materials": {
        # Paint and plaster: a photograph at a few percent contrast, so walls stay low-texture.
        "wall_white": {"texture": "ela", "scale_m": 2.0, "contrast": 0.2, "color": [0.92, 0.91, 0.87]},
        "wall_corridor": {"texture": "aloe", "scale_m": 2.5, "contrast": 0.2, "color": [0.84, 0.86, 0.80]},
        "ceiling": {"texture": "ceiling_tile", "scale_m": 0.6, "contrast": 0.35, "color": [0.95, 0.95, 0.94]},
        "vent": {"texture": "vent", "scale_m": 0.0, "color": [0.95, 0.95, 0.95]},
        "sprinkler": {"color": [0.78, 0.68, 0.45]},
        "smoke_detector": {"color": [0.97, 0.97, 0.96]},
        "carpet": {"texture": "baboon", "scale_m": 0.5, "contrast": 0.6, "color": [0.36, 0.36, 0.42]},
        "lino": {"texture": "baboon", "scale_m": 0.6, "contrast": 0.5, "color": [0.55, 0.53, 0.50]},
        # stuff.jpg is a photograph of a light wooden table top: grain, a pen, a ball.
        "wood": {"texture": "stuff", "scale_m": 0.3, "color": [0.95, 0.8, 0.62]},
        "wood_dark": {"texture": "stuff", "scale_m": 0.3, "color": [0.6, 0.45, 0.32]},
        "door": {"texture": "stuff", "scale_m": 2.0, "color": [0.85, 0.7, 0.52]},
        "door_frame": {"color": [0.94, 0.94, 0.92]},
        "skirting": {"color": [0.3, 0.27, 0.24]},
        "radiator": {"color": [0.95, 0.95, 0.94]},
        "radiator_rib": {"color": [0.8, 0.8, 0.8]},
        "cabinet_grey": {"color": [0.6, 0.62, 0.64]},
        "locker": {"color": [0.45, 0.55, 0.68]},
        "cork": {"texture": "baboon", "scale_m": 0.12, "contrast": 0.8, "color": [0.75, 0.55, 0.35]},
        "note_text": {"texture": "textN", "color": [1, 1, 1]},
        "notice_text": {"texture": "textN", "color": [1, 1, 1]},
        "notice_text2": {"texture": "text", "color": [0.95, 0.97, 1]},
        "notice_sudoku": {"texture": "sudoku", "color": [1, 1, 0.92]},
        "note_text2": {"texture": "text", "color": [1, 1, 0.9]},
        "note_sudoku": {"texture": "sudoku", "color": [1, 1, 1]},
        "note_notes": {"texture": "notes", "color": [1, 1, 1]},
        "note_yellow": {"texture": "textN", "color": [1, 0.95, 0.45]},
        "note_photo": {"texture": "chicky", "color": [1, 1, 1]},
        "mug_white": {"color": [0.96, 0.96, 0.95]},
        # Book spines: a printed cookie box and a page of text, tinted.
        "book_red": {"texture": "box", "color": [0.8, 0.25, 0.2]},
        "book_blue": {"texture": "textN", "color": [0.3, 0.4, 0.75]},
        "book_green": {"texture": "box", "color": [0.3, 0.6, 0.35]},
        "book_cream": {"texture": "textN", "color": [0.95, 0.9, 0.75]},
        "book_black": {"texture": "box", "color": [0.35, 0.33, 0.33]},
        "book_ochre": {"texture": "box", "color": [0.85, 0.65, 0.25]},
        "metal": {"color": [0.62, 0.63, 0.65]},
        "plastic_dark": {"color": [0.12, 0.12, 0.13]},
        "plastic_light": {"color": [0.82, 0.82, 0.80]},
        "fabric_blue": {"color": [0.20, 0.27, 0.42]},
        "fabric_grey": {"texture": "baboon", "scale_m": 0.4, "color": [0.45, 0.45, 0.5]},
        "frame": {"color": [0.15, 0.13, 0.12]},
        "pot": {"color": [0.55, 0.33, 0.22]},
        "leaves": {"texture": "stuff", "scale_m": 0.6, "color": [0.35, 0.6, 0.3]},
        "whiteboard": {"texture": "text", "color": [1.0, 1.0, 1.0]},
        "notice_board": {"texture": "box_scene", "color": [0.95, 0.9, 0.8]},
        "window_frame": {"color": [0.93, 0.93, 0.91]},
        "seal": {"color": [0.08, 0.08, 0.09]},
        "outside_facade": {"texture": "building", "scale_m": 12.0, "color": [0.9, 0.95, 1.0],
                           "no_depth": True, "unlit": True},
        "outside_street": {"texture": "leuven", "scale_m": 8.0, "color": [0.6, 0.6, 0.6],
                           "no_depth": True, "unlit": True},
        "screen_desktop": {"texture": "aero3", "color": [0.85, 0.85, 0.9], "no_depth": True, "unlit": True},
        "screen_tv": {"texture": "leuvenB", "color": [0.9, 0.9, 0.9], "no_depth": True, "unlit": True},
        "projection": {"color": [0.95, 0.95, 0.95]},
        "light_panel": {"color": [1.0, 1.0, 0.97], "unlit": True},
        "lamp_shade": {"color": [0.95, 0.88, 0.7], "unlit": True},
        "lamp_shade_red": {"color": [0.75, 0.15, 0.12]},
        "switch_plate": {"color": [0.97, 0.97, 0.95]},
        "thermostat_face": {"texture": "notes", "color": [0.9, 0.92, 0.95]},
        "printer_front": {"texture": "box_scene", "color": [0.8, 0.8, 0.8]},
        "books1": {"texture": "stuff", "color": [1, 1, 1]},
        "books2": {"texture": "box_scene", "color": [1, 0.95, 0.85]},
        "books3": {"texture": "fruits", "color": [0.9, 0.9, 0.9]},
        "poster_graf": {"texture": "graf"}, "poster_graf3": {"texture": "graf3"},
        "poster_starry": {"texture": "starry"}, "poster_books": {"texture": "books"},
        "poster_basketball": {"texture": "basketball"}, "poster_board": {"texture": "board"},
        "poster_fruits": {"texture": "fruits"}, "poster_baboon": {"texture": "baboon"},
        "poster_home": {"texture": "home"}, "poster_butterfly": {"texture": "butterfly"},
        "poster_messi": {"texture": "messi"}, "poster_fish": {"texture": "fish"},
        "poster_smarties": {"texture": "smarties"}, "poster_whale": {"texture": "whale"},
        "poster_aloe": {"texture": "aloe"}, "poster_apple": {"texture": "apple"},
        "poster_orange": {"texture": "orange"}, "poster_squirrel": {"texture": "squirrel"},
        "poster_suzanne": {"texture": "suzanne"}, "poster_blox": {"texture": "blox"},
        "poster_cards": {"texture": "cards"}, "poster_sudoku": {"texture": "sudoku"},
        "poster_linux": {"texture": "linux"}, "poster_plate": {"texture": "plate"},
        "poster_pic1": {"texture": "pic1"}, "poster_pic5": {"texture": "pic5"},
        "papers": {"texture": "text", "color": [1, 1, 1]},
    },
    "rooms": [
        {"name": "corridor", "min": [0.0, 0.0], "max": [30.0, YC]},
        {"name": "lab", "min": [0.0, YC], "max": [10.0, Y1]},
        {"name": "meeting_room", "min": [10.0, YC], "max": [20.0, Y1]},
        {"name": "office", "min": [20.0, YC], "max": [30.0, Y1]},
    ],
    # A closed walk (metres, floor plan) through every room; the walker loops it.
    "tour": [[2.0, 1.2], [4.6, 1.3], [4.6, 3.2], [3.2, 4.2], [2.4, 6.2], [3.2, 8.5], [5.5, 8.7],
             [7.8, 7.8], [8.4, 5.5], [7.6, 3.8], [6.8, 4.6], [7.4, 7.2], [8.8, 8.8], [10.0, 8.8],
             [11.4, 8.4], [12.0, 6.0], [12.3, 4.2], [14.6, 3.7], [17.4, 4.0], [18.3, 6.4],
             [18.2, 8.6], [20.0, 8.8], [21.6, 8.4], [21.6, 6.2], [22.6, 4.3], [25.0, 3.8],
             [27.3, 4.2], [27.3, 6.8], [25.8, 8.0], [24.6, 6.5], [24.6, 3.6], [24.6, 1.3],
             [19.0, 1.2], [14.0, 1.1], [8.0, 1.2]],
    "boxes": boxes,
    "appliances": appliances,
}
with open("sim/office_scene.json", "w") as f:
    json.dump(scene, f, indent=1)
print(len(boxes), "boxes,", len(appliances), "appliances")
