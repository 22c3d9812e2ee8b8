#!/usr/bin/env python3
"""The phone page and the labelling page of `sightmap serve`, in a real headless Chromium.

A real server (the built binary, 127.0.0.1, a free port) on a real model: 90 keyframes of the
simulated walk at their true poses, every scene appliance labelled. Debian's chromium and
chromedriver, driven by python3-selenium:

- the phone page uploads session-2 photos through its file input; the appliance names it shows
  (and their order) must be those of `sightmap locate --json` on the same photo, and an unmatched
  photo must say why in plain words;
- tapping an appliance shows its details with every action disabled, and why;
- the labelling page opens a keyframe, clicks a pixel and adds a label; the stored point must be
  the one `sightmap label list --json` reports, at the clicked pixel, and the same world point
  `sightmap label add --keyframe --pixel` makes of that pixel;
- a read-only server's labelling page shows no editing controls, and its write endpoints answer
  403; with a token, edits without it answer 401;
- on a copy of the model whose keyframes repeat 10 m higher (a building whose floors repeat), an
  ambiguous photo's page names both places with the appliances `sightmap locate --json` lists
  for each.

Screenshots of both pages at 360x740 (a phone) go to OUT_DIR for people to look at.

Usage: web_pages_test.py SIGHTMAP_BINARY OUT_DIR. Exits 77 (skipped) when Chromium, ChromeDriver or
Selenium is missing, unless CI=true, where that is a failure.
"""

import base64
import json
import os
import re
import shutil
import sqlite3
import subprocess
import sys
import tempfile
import time
import traceback
import urllib.error
import urllib.request

SKIPPED = 77
PHONE_VIEWPORT = (360, 740)


def skip_or_fail(reason):
    if os.environ.get("CI") == "true":
        print(f"FAIL: {reason} (CI=true: the browser tests must run; scripts/setup.sh installs "
              "chromium, chromium-driver and python3-selenium)")
        sys.exit(1)
    print(f"SKIP: {reason}: install chromium, chromium-driver and python3-selenium "
          "(scripts/setup.sh) to run the browser tests")
    sys.exit(SKIPPED)


try:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support import expected_conditions
    from selenium.webdriver.support.ui import WebDriverWait
except ImportError:
    skip_or_fail("python3-selenium is not installed")

CHROMIUM = shutil.which("chromium")
CHROMEDRIVER = shutil.which("chromedriver")
if not CHROMIUM or not CHROMEDRIVER:
    skip_or_fail("chromium or chromedriver is not installed")


class Failure(Exception):
    pass


def expect(condition, message):
    if not condition:
        raise Failure(message)


def run(sightmap, *args):
    result = subprocess.run([sightmap, *args], capture_output=True, text=True, timeout=300)
    if result.returncode != 0:
        raise Failure(f"sightmap {' '.join(args)} exited {result.returncode}: {result.stderr}")
    return result.stdout


class Server:
    """`sightmap serve ARGS` on a free port; stopped with SIGTERM."""

    def __init__(self, sightmap, *args):
        self.process = subprocess.Popen(
            [sightmap, "serve", "--port", "0", *args], stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL, text=True)
        self.output = ""
        deadline = time.time() + 120
        while time.time() < deadline:
            line = self.process.stdout.readline()
            if not line:
                raise Failure(f"sightmap serve exited: {self.output}")
            self.output += line
            match = re.search(r"labelling page (http://[0-9.]+:[0-9]+)", line)
            if match:
                self.url = match.group(1)
                return
        raise Failure("sightmap serve did not start in 120 s")

    def stop(self):
        self.process.terminate()
        try:
            self.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.process.kill()

    def request(self, method, path, body=None, headers=None):
        """(status, JSON answer) of one request."""
        data = json.dumps(body).encode() if body is not None else None
        request = urllib.request.Request(self.url + path, data=data, method=method,
                                         headers={"Content-Type": "application/json",
                                                  **(headers or {})})
        try:
            with urllib.request.urlopen(request, timeout=30) as response:
                return response.status, json.loads(response.read())
        except urllib.error.HTTPError as error:
            return error.code, json.loads(error.read())


def make_browser():
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for argument in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                     "--disable-gpu", f"--window-size={PHONE_VIEWPORT[0]},{PHONE_VIEWPORT[1]}"):
        options.add_argument(argument)
    browser = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    # The viewport itself, not the window, is the phone's 360x740 screen.
    browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {
        "width": PHONE_VIEWPORT[0], "height": PHONE_VIEWPORT[1], "deviceScaleFactor": 2,
        "mobile": True})
    browser.set_page_load_timeout(60)
    return browser


def wait_for(browser, condition, what, seconds=60):
    try:
        return WebDriverWait(browser, seconds, poll_frequency=0.1).until(lambda b: condition(b))
    except Exception as error:
        raise Failure(f"timed out waiting for {what}") from error


def build_model(sightmap, work):
    photos = os.path.join(work, "photos")
    model = os.path.join(work, "model.db")
    run(sightmap, "sim", "generate", "--session", "2", "--seed", "7", "--frames", "0",
        "--queries", "12", "--out", photos)
    # The same photos as a phone's camera takes them, larger than the server matches at.
    run(sightmap, "sim", "generate", "--session", "2", "--seed", "7", "--frames", "0",
        "--queries", "6", "--query-size", "2560x1920", "--out", os.path.join(work, "big"))
    run(sightmap, "map", "--source", "sim:office?seed=7&fps=1&frames=90", "--ground-truth-poses",
        "--model", model, "--headless")
    run(sightmap, "label", "import", "--model", model, "--from-scene",
        os.path.join(photos, "appliances.json"))
    def jpegs(folder):
        queries = os.path.join(folder, "queries")
        return sorted(os.path.join(queries, name) for name in os.listdir(queries)
                      if name.endswith(".jpg"))
    return model, jpegs(photos), jpegs(os.path.join(work, "big"))


def add_floor_above(model, repeated, height_m):
    """A copy of `model` whose keyframes appear again `height_m` higher, unlabelled: a building
    whose floors repeat, where a photo of one fits the other as well."""
    with sqlite3.connect(model) as source, sqlite3.connect(repeated) as target:
        source.backup(target)
    db = sqlite3.connect(repeated)
    offset = db.execute("SELECT MAX(id) FROM keyframes").fetchone()[0]

    def copy_rows(table, changes):
        columns = [row[1] for row in db.execute(f"PRAGMA table_info({table})")]
        values = [changes.get(column, column) for column in columns]
        db.execute(f"INSERT INTO {table} ({', '.join(columns)}) "
                   f"SELECT {', '.join(values)} FROM {table}")

    copy_rows("keyframes", {"id": f"id + {offset}", "timestamp_ns": "timestamp_ns + 1000000000000",
                            "tz": f"tz + {height_m}", "odom_tz": f"odom_tz + {height_m}"})
    for table in ("keyframe_images", "features", "photo_features"):
        copy_rows(table, {"keyframe_id": f"keyframe_id + {offset}"})
    db.commit()
    db.close()


def locate_answers(sightmap, model, photos):
    """`sightmap locate --json` on each photo."""
    return {photo: json.loads(run(sightmap, "locate", "--model", model, photo, "--json"))
            for photo in photos}


def upload(browser, photo):
    browser.execute_script("document.body.dataset.state = ''")
    browser.find_element(By.ID, "photo-input").send_keys(photo)
    state = wait_for(browser, lambda b: b.execute_script(
        "return ['matched', 'unmatched', 'error'].includes(document.body.dataset.state) && "
        "document.body.dataset.state"), f"the answer to {os.path.basename(photo)}")
    return state


def test_phone_page(browser, server, sightmap, model, answers, big_photos, out_dir):
    browser.get(server.url + "/")
    matched = [p for p, a in answers.items() if a["matched"] and a["appliances"]]
    unmatched = [p for p, a in answers.items() if not a["matched"]]
    expect(len(matched) >= 2, f"only {len(matched)} of {len(answers)} photos match with "
                              "appliances in view: the model or the photos changed")
    round_trips = []
    for photo in matched[:3]:
        expect(upload(browser, photo) == "matched", f"{photo} was not matched on the page")
        shown = [item.get_attribute("data-name") for item in
                 browser.find_elements(By.CSS_SELECTOR, "#appliances li")]
        expected = [a["name"] for a in answers[photo]["appliances"]]
        expect(shown == expected, f"{os.path.basename(photo)}: the page shows {shown}, "
                                  f"locate --json says {expected}")
        classes = [item.get_attribute("class") for item in
                   browser.find_elements(By.CSS_SELECTOR, "#appliances li")]
        for appliance, css in zip(answers[photo]["appliances"], classes):
            wanted = ("hidden" if not appliance["visible"] else
                      "partly" if appliance["visible_share"] < 0.999 else "visible")
            expect(css == wanted, f"{appliance['name']} drawn as {css}, not {wanted}")
        round_trips.append(float(browser.execute_script("return document.body.dataset.roundTripS")))
        print(f"phone page: {os.path.basename(photo)} -> {shown}")
    print("phone page: round trips " + ", ".join(f"{s:.2f} s" for s in round_trips) +
          " (1280x960 JPEG, upload to drawn answer)")

    # The photo is drawn at its own size with the marks on it.
    size = browser.execute_script(
        "const c = document.getElementById('photo'); return [c.width, c.height]")
    expect(size == [1280, 960], f"the photo is drawn at {size}, not 1280x960")
    browser.save_screenshot(os.path.join(out_dir, "phone-matched.png"))

    # Tapping the nearest appliance: its details, every action disabled, and why.
    first = browser.find_element(By.CSS_SELECTOR, "#appliances li button")
    first.click()
    wait_for(browser, lambda b: b.find_element(By.ID, "details").is_displayed() and
             "(" in b.find_element(By.ID, "details-points").text, "the appliance's details")
    expect(browser.find_element(By.ID, "details-name").text ==
           answers[matched[:3][-1]]["appliances"][0]["name"],
           "the details name another appliance than the one tapped")
    actions = browser.find_elements(By.CSS_SELECTOR, "#details-actions button")
    expect(actions and all(not a.is_enabled() for a in actions),
           "the actions must be shown disabled until a building system is connected")
    expect("No building system" in browser.find_element(By.ID, "details-actions-why").text,
           "the disabled actions must say why")
    browser.save_screenshot(os.path.join(out_dir, "phone-details.png"))

    # Photos larger than the server needs are downscaled by the page before they are sent: what
    # it shows must be `locate --json` on the very bytes it sent, and at least one must match.
    matched_big = 0
    for index, photo in enumerate(big_photos):
        upload(browser, photo)
        sent = browser.execute_script("return document.body.dataset.upload")
        size, sent_bytes = sent.split()[:2]
        expect(size == "1280x960" and int(sent_bytes) < os.path.getsize(photo),
               f"the page sent {sent} of a 2560x1920 photo")
        encoded = browser.execute_async_script(
            "const done = arguments[arguments.length - 1];"
            "const reader = new FileReader();"
            "reader.onload = () => done(reader.result.split(',')[1]);"
            "reader.readAsDataURL(window.sightmapLastUpload);")
        sent_path = os.path.join(os.path.dirname(photo), f"sent-{index}.jpg")
        with open(sent_path, "wb") as file:
            file.write(base64.b64decode(encoded))
        expected = json.loads(run(sightmap, "locate", "--model", model, sent_path, "--json"))
        shown = [item.get_attribute("data-name") for item in
                 browser.find_elements(By.CSS_SELECTOR, "#appliances li")]
        expect(shown == [a["name"] for a in expected["appliances"]],
               f"{os.path.basename(photo)} downscaled: the page shows {shown}, locate on the "
               f"sent bytes {[a['name'] for a in expected['appliances']]}")
        print(f"phone page: 2560x1920 {os.path.basename(photo)} sent as {size} "
              f"({int(sent_bytes) // 1024} of {os.path.getsize(photo) // 1024} KB) -> {shown}")
        if expected["matched"] and shown:
            matched_big += 1
            if matched_big == 2:
                break
    expect(matched_big >= 1, "no downscaled photo matched")

    # An unmatched photo says why in words a person understands.
    if unmatched:
        expect(upload(browser, unmatched[0]) == "unmatched", "an unmatched photo was matched")
        advice = browser.find_element(By.ID, "advice").text
        expect(advice == answers[unmatched[0]]["advice"] and advice,
               f"the page advises '{advice}', locate says '{answers[unmatched[0]]['advice']}'")
        print(f"phone page: unmatched photo -> '{advice}'")
        browser.save_screenshot(os.path.join(out_dir, "phone-unmatched.png"))


def click_pixel(browser, canvas, u, v):
    """Clicks the canvas where image pixel (u, v) is drawn; returns the pixel the page chose."""
    box = browser.execute_script(
        "const c = arguments[0]; const r = c.getBoundingClientRect();"
        "return [r.width, r.height, c.width, c.height]", canvas)
    x = (u + 0.5) * box[0] / box[2]
    y = (v + 0.5) * box[1] / box[3]
    # Selenium 4 offsets from the element's centre.
    ActionChains(browser).move_to_element_with_offset(
        canvas, int(round(x - box[0] / 2)), int(round(y - box[1] / 2))).click().perform()


def test_label_page(browser, server, sightmap, model, work, out_dir):
    browser.get(server.url + "/label")
    wait_for(browser, lambda b: b.execute_script("return document.body.dataset.ready"),
             "the labelling page to load")
    thumbs = browser.find_elements(By.CSS_SELECTOR, "#thumbs .thumb")
    expect(len(thumbs) == 90, f"{len(thumbs)} keyframe thumbnails, not 90")
    # The first row of thumbnails is on screen: they load (lazily) and decode.
    wait_for(browser, lambda b: b.execute_script(
        "return [...document.querySelectorAll('#thumbs img')].slice(0, 3)"
        ".every(i => i.complete && i.naturalWidth === 160)"), "the first thumbnails")
    browser.save_screenshot(os.path.join(out_dir, "label-list.png"))
    keyframe = 40
    browser.find_element(By.CSS_SELECTOR, f'#thumbs .thumb[data-keyframe="{keyframe}"]').click()
    wait_for(browser, lambda b: b.execute_script("return document.body.dataset.keyframe") ==
             str(keyframe), "the keyframe to open")
    canvas = browser.find_element(By.ID, "keyframe")
    click_pixel(browser, canvas, 320, 200)
    clicked = browser.find_element(By.ID, "clicked").text
    match = re.search(r"Pixel (\d+), (\d+)", clicked)
    expect(match, f"the click chose no pixel: '{clicked}'")
    u, v = int(match.group(1)), int(match.group(2))
    expect(abs(u - 320) <= 1 and abs(v - 200) <= 1,
           f"clicking image pixel 320,200 chose {u},{v}")
    browser.find_element(By.ID, "label-name").send_keys("web projector")
    browser.find_element(By.ID, "label-type").send_keys("projector")
    browser.find_element(By.ID, "add-point").click()
    wait_for(browser, lambda b: b.execute_script("return document.body.dataset.lastAdded") ==
             "web projector", "the label to be added")
    message = browser.find_element(By.ID, "message").text
    expect(message.startswith("created 'web projector' (projector)"),
           f"the page says '{message}'")
    browser.save_screenshot(os.path.join(out_dir, "label-added.png"))

    labels = json.loads(run(sightmap, "label", "list", "--model", model, "--json"))["labels"]
    stored = [label for label in labels if label["name"] == "web projector"]
    expect(len(stored) == 1 and stored[0]["type"] == "projector", "label list --json lacks it")
    source = stored[0]["point_sources"][0]
    expect(source["source"] == "keyframe_pixel" and source["keyframe"] == keyframe and
           source["pixel"] == [u, v], f"stored as {source}, clicked {keyframe} at {u},{v}")
    # The same world point as the command line makes of that pixel, on a copy of the model.
    copy = os.path.join(work, "copy.db")
    shutil.copy(model, copy)
    run(sightmap, "label", "add", "--model", copy, "--name", "cli", "--keyframe", str(keyframe),
        "--pixel", f"{u},{v}")
    cli = [label for label in json.loads(run(sightmap, "label", "list", "--model", copy,
                                             "--json"))["labels"] if label["name"] == "cli"]
    distance = sum((a - b) ** 2 for a, b in zip(cli[0]["points"][0], stored[0]["points"][0])) ** 0.5
    expect(distance < 1e-9, f"the page's point is {distance} m from label add's")
    print(f"label page: keyframe {keyframe} pixel {u},{v} -> {stored[0]['points'][0]} "
          "(= sightmap label add --keyframe --pixel)")

    # The new label is drawn on the keyframe, and listed with the keyframes that see it.
    drawn = browser.execute_script(
        "return state.seen.map(l => l.name)")
    expect("web projector" in drawn, f"the keyframe draws {drawn}")
    row = browser.find_element(By.CSS_SELECTOR, 'tr[data-label-name="web projector"]')
    expect(row.find_elements(By.CSS_SELECTOR, ".seen .thumb"), "no keyframe listed as seeing it")

    # Rename it in the list, then remove it.
    name = row.find_element(By.CSS_SELECTOR, "input.label-name")
    name.clear()
    name.send_keys("web projector 2")
    row.find_element(By.CSS_SELECTOR, "button.save").click()
    wait_for(browser, lambda b: b.find_elements(
        By.CSS_SELECTOR, 'tr[data-label-name="web projector 2"]'), "the rename")
    row = browser.find_element(By.CSS_SELECTOR, 'tr[data-label-name="web projector 2"]')
    row.find_element(By.CSS_SELECTOR, "button.remove").click()
    wait_for(browser, expected_conditions.alert_is_present(), "the removal's confirmation")
    browser.switch_to.alert.accept()
    wait_for(browser, lambda b: not b.find_elements(
        By.CSS_SELECTOR, 'tr[data-label-name="web projector 2"]'), "the removal")
    names = [label["name"] for label in
             json.loads(run(sightmap, "label", "list", "--model", model, "--json"))["labels"]]
    expect("web projector" not in names and "web projector 2" not in names,
           "the removed label is still stored")


def test_ambiguous_photo(browser, sightmap, model, photos, work, out_dir):
    """On a building whose floors repeat, a photo is ambiguous: the page names both places and,
    under each, the appliances `sightmap locate --json` lists for it."""
    repeated = os.path.join(work, "repeated.db")
    add_floor_above(model, repeated, 10.0)
    answers = locate_answers(sightmap, repeated, photos)
    ambiguous = [p for p, a in answers.items()
                 if a.get("reason_code") == "ambiguous" and a["possible_places"]]
    expect(ambiguous, "no photo is ambiguous on a model whose floors repeat")
    server = Server(sightmap, "--model", repeated)
    try:
        browser.get(server.url + "/")
        photo = ambiguous[0]
        expect(upload(browser, photo) == "unmatched", f"{photo} was not answered ambiguous")
        places = answers[photo]["possible_places"]
        lists = browser.find_elements(By.CSS_SELECTOR, "#possible ol")
        expect(len(lists) == len(places) == 2,
               f"the page lists {len(lists)} places, locate --json {len(places)}")
        for number, (shown_list, place) in enumerate(zip(lists, places), start=1):
            shown = [item.get_attribute("data-name")
                     for item in shown_list.find_elements(By.CSS_SELECTOR, "li")]
            expected = [a["name"] for a in place["appliances"]]
            expect(shown == expected, f"place {number}: the page shows {shown}, locate --json "
                                      f"says {expected}")
            # No marks are drawn for a possible place, so its list is not numbered like them.
            expect(not shown_list.find_elements(By.CSS_SELECTOR, ".badge"),
                   f"place {number}'s list carries the photo's mark numbers")
        intro = browser.find_element(By.CSS_SELECTOR, "#possible p").text
        expect(intro == "It is one of these 2 places:", f"the page says '{intro}'")
        status = browser.find_element(By.ID, "status").text
        expect(status.startswith("It could be one of 2 places"), f"the status says '{status}'")
        browser.save_screenshot(os.path.join(out_dir, "phone-ambiguous.png"))
        print(f"phone page: ambiguous photo {os.path.basename(photo)} -> "
              f"{[[a['name'] for a in p['appliances']] for p in places]}")
    finally:
        server.stop()


def test_read_only_and_token(browser, sightmap, model):
    server = Server(sightmap, "--model", model, "--read-only")
    try:
        browser.get(server.url + "/label")
        wait_for(browser, lambda b: b.execute_script("return document.body.dataset.ready"),
                 "the read-only labelling page")
        expect(browser.execute_script("return document.body.dataset.editable") == "false",
               "the read-only page says it is editable")
        expect(not browser.find_element(By.ID, "add-form").is_displayed(),
               "a read-only page shows the add form")
        expect(not browser.find_elements(By.CSS_SELECTOR, "button.remove"),
               "a read-only page shows remove buttons")
        status, answer = server.request("POST", "/api/labels",
                                        {"name": "x", "keyframe": 1, "pixel": [1, 1]})
        expect(status == 403 and "read-only" in answer["error"], f"{status} {answer}")
        status, _ = server.request("DELETE", "/api/labels/1")
        expect(status == 403, f"DELETE on a read-only server answered {status}")
    finally:
        server.stop()
    server = Server(sightmap, "--model", model, "--token", "s3cret")
    try:
        body = {"name": "tokened", "keyframe": 40, "pixel": [320, 200]}
        status, _ = server.request("POST", "/api/labels", body)
        expect(status == 401, f"an edit without the token answered {status}")
        status, _ = server.request("POST", "/api/labels", body, {"X-Sightmap-Token": "wrong"})
        expect(status == 401, f"an edit with a wrong token answered {status}")
        status, answer = server.request("POST", "/api/labels", body, {"X-Sightmap-Token": "s3cret"})
        expect(status == 200 and answer["created"], f"{status} {answer}")
        status, _ = server.request("DELETE", f"/api/labels/{answer['label']['id']}", None,
                                   {"X-Sightmap-Token": "s3cret"})
        expect(status == 200, f"removing with the token answered {status}")
    finally:
        server.stop()
    # Off loopback without --token, one is made up and printed with the labelling page's address.
    server = Server(sightmap, "--model", model, "--host", "0.0.0.0")
    try:
        match = re.search(r"/label\?token=([0-9a-f]+)", server.output)
        expect(match, f"no edit token printed: {server.output}")
        body = {"name": "printed", "keyframe": 40, "pixel": [320, 200]}
        status, _ = server.request("POST", "/api/labels", body)
        expect(status == 401, f"an edit without the printed token answered {status}")
        status, answer = server.request("POST", "/api/labels", body,
                                        {"X-Sightmap-Token": match.group(1)})
        expect(status == 200, f"an edit with the printed token answered {status} {answer}")
        server.request("DELETE", f"/api/labels/{answer['label']['id']}", None,
                       {"X-Sightmap-Token": match.group(1)})
        status, _ = server.request("GET", "/appliances")
        expect(status == 200, "the phone side needs no token")
    finally:
        server.stop()
    print("read-only: no editing controls, writes 403; --token: writes without it 401; "
          "--host 0.0.0.0: a printed token")


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    sightmap, out_dir = sys.argv[1], sys.argv[2]
    os.makedirs(out_dir, exist_ok=True)
    work = tempfile.mkdtemp(prefix="sightmap-web-")
    browser = None
    server = None
    try:
        model, photos, big_photos = build_model(sightmap, work)
        answers = locate_answers(sightmap, model, photos)
        server = Server(sightmap, "--model", model)
        browser = make_browser()
        test_phone_page(browser, server, sightmap, model, answers, big_photos, out_dir)
        test_label_page(browser, server, sightmap, model, work, out_dir)
        server.stop()
        server = None
        test_read_only_and_token(browser, sightmap, model)
        test_ambiguous_photo(browser, sightmap, model, photos, work, out_dir)
        print(f"screenshots (360x740 viewport) in {out_dir}")
        print("PASS")
        return 0
    except Failure as failure:
        print(f"FAIL: {failure}")
        if browser:
            browser.save_screenshot(os.path.join(out_dir, "failure.png"))
            print(f"the page at the failure: {os.path.join(out_dir, 'failure.png')}")
        return 1
    except Exception:  # a crash of the test itself must fail it, with the trace
        traceback.print_exc()
        return 1
    finally:
        if browser:
            browser.quit()
        if server:
            server.stop()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
