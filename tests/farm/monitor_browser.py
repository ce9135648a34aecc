#!/usr/bin/python3
"""Drives the coordinator's web monitor in headless Chromium (chromium-driver + python3-selenium).

Usage: monitor_browser.py URL TOKEN OUT_DIR

Opens URL, gives TOKEN to the login form (the farm requires one), writes OUT_DIR/ready once the
farm page shows, and waits for OUT_DIR/jobs.json ({"done": JOB_DONE, "cancel": JOB_CANCEL}: the
test submits the jobs once the page is open, so the page sees them render). Then:
  1. reads job JOB_DONE's row, the workers' rows and the ray servers' from the farm page;
  2. opens JOB_DONE's page, waits until it says the job is done and the preview holds every
     tile of the frame, and writes the pixels the browser decoded from the preview image
     (RGBA, row-major) to OUT_DIR/preview.rgba, its size to OUT_DIR/preview.json;
  3. takes screenshots: OUT_DIR/monitor-farm.png (the farm page, in step 1) and
     OUT_DIR/monitor.png (the job page);
  4. opens JOB_CANCEL's page, clicks "Cancel job", accepts the confirmation, and waits for the
     page to show the job cancelled.
Prints one JSON object with what it read. Exits non-zero, saying why, on any failure.
"""
import base64
import json
import os
import sys
import time

from selenium import webdriver
from selenium.common.exceptions import StaleElementReferenceException, WebDriverException
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.support import expected_conditions as ec
from selenium.webdriver.support.ui import WebDriverWait

url, token, out_dir = sys.argv[1:4]


def fail(message, driver=None):
    if driver is not None:
        driver.save_screenshot(out_dir + "/failure.png")
        try:
            for entry in driver.get_log("browser"):
                print("browser:", entry.get("message"), file=sys.stderr)
        except WebDriverException:
            pass
    print("monitor_browser: " + message, file=sys.stderr)
    sys.exit(1)


options = webdriver.ChromeOptions()
options.binary_location = "/usr/bin/chromium"
for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1000",
            "--force-color-profile=srgb", "--disable-gpu"):
    options.add_argument(arg)
options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
try:
    driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
except WebDriverException as e:
    fail("cannot start Chromium: %s" % e.msg)

# A wait polls again when the element it looked at was redrawn meanwhile (see rows()).
wait = WebDriverWait(driver, 30, poll_frequency=0.1, ignored_exceptions=[StaleElementReferenceException])


def rows(selector, classes):
    """The text of each row's cells of the given classes, read in one script run: the tables are
    redrawn every second, so elements found by one WebDriver call can be gone by the next one
    (a StaleElementReferenceException, seen on a loaded machine)."""
    return driver.execute_script(
        """
        const [selector, classes] = arguments;
        return [...document.querySelectorAll(selector)].map(r => Object.fromEntries(
            classes.map(c => { const e = r.querySelector('.' + c); return [c, e ? e.textContent.trim() : null]; })));
        """, selector, classes)


report = {}
try:
    driver.get(url)
    # The farm has a client token: the monitor asks for it before showing anything.
    wait.until(ec.visibility_of_element_located((By.ID, "login")))
    report["asked_for_token"] = True
    driver.find_element(By.ID, "token").send_keys(token)
    driver.find_element(By.CSS_SELECTOR, "#login button").click()

    wait.until(ec.visibility_of_element_located((By.ID, "farm")))
    open(out_dir + "/ready", "w").close()
    deadline = time.time() + 60
    while not os.path.exists(out_dir + "/jobs.json"):
        if time.time() > deadline:
            fail("no jobs.json from the test after 60 s", driver)
        time.sleep(0.05)
    with open(out_dir + "/jobs.json") as f:
        jobs = json.load(f)
    job_done, job_cancel = jobs["done"], jobs["cancel"]

    # 1. The farm page: the job and both workers.
    wait.until(ec.presence_of_element_located((By.CSS_SELECTOR, 'tr[data-job="%s"]' % job_done)))
    report["job"] = rows('tr[data-job="%s"]' % job_done, ["job-" + k for k in ("id", "name", "state", "priority")])[0]
    report["job"] = {k[len("job-"):]: v for k, v in report["job"].items()}
    wait.until(lambda d: len(rows("#workers tr[data-worker]", ["worker-name"])) >= 2)
    report["workers"] = sorted(r["worker-name"] for r in rows("#workers tr[data-worker]", ["worker-name"]))
    # ... and the ray server announced to the coordinator.
    wait.until(lambda d: len(rows("#rayservers tr[data-rayserver]", ["rayserver-address"])) >= 1)
    report["ray_servers"] = sorted(r["rayserver-address"]
                                   for r in rows("#rayservers tr[data-rayserver]", ["rayserver-address"]))

    # 2. The job's page, reached by clicking its row; the job finishes while it is open.
    driver.save_screenshot(out_dir + "/monitor-farm.png")
    report["step"] = "job page"
    # The table is redrawn every second: click the row as it is now.
    wait.until(lambda d: d.find_element(By.CSS_SELECTOR, 'tr[data-job="%s"]' % job_done).click() or True)
    wait.until(ec.visibility_of_element_located((By.ID, "job")))
    report["step"] = "job done" 
    long_wait = WebDriverWait(driver, 90, poll_frequency=0.2, ignored_exceptions=[StaleElementReferenceException])
    long_wait.until(ec.text_to_be_present_in_element((By.CSS_SELECTOR, 'dd[data-fact="state"]'), "done"))
    job = driver.execute_script("return fetch('api/jobs/%s', {headers: {Authorization: 'Bearer ' + "
                                "sessionStorage.getItem('tessera-token')}}).then(r => r.json())" % job_done)
    tiles = job["tiles_per_frame"]
    report["step"] = "preview complete" 
    long_wait.until(lambda d: d.find_element(By.ID, "preview").get_attribute("data-tiles") == str(tiles))
    report["preview_tiles"] = tiles
    report["tile_map_workers"] = driver.find_element(By.ID, "tile-map").get_attribute("data-workers")
    report["frames_rows"] = len(driver.find_elements(By.CSS_SELECTOR, "#frames tbody tr"))
    # The pixels the browser decoded from the image it shows.
    pixels = driver.execute_script(
        """
        const img = document.getElementById('preview');
        const c = document.createElement('canvas');
        c.width = img.naturalWidth; c.height = img.naturalHeight;
        const g = c.getContext('2d', {colorSpace: 'srgb'});
        g.drawImage(img, 0, 0);
        const data = g.getImageData(0, 0, c.width, c.height).data;
        let s = '';
        for (let i = 0; i < data.length; i += 8192) s += String.fromCharCode.apply(null, data.subarray(i, i + 8192));
        return [c.width, c.height, btoa(s)];
        """)
    width, height, b64 = pixels
    with open(out_dir + "/preview.rgba", "wb") as f:
        f.write(base64.b64decode(b64))
    with open(out_dir + "/preview.json", "w") as f:
        json.dump({"width": width, "height": height}, f)

    # 3. The picture of the monitor for docs/.
    driver.save_screenshot(out_dir + "/monitor.png")

    # 4. Cancel the other job from its page.
    report["step"] = "cancel" 
    driver.get(url + "#/job/" + job_cancel)
    wait.until(ec.text_to_be_present_in_element((By.ID, "job-title"), job_cancel))
    report["cancel_state_before"] = driver.find_element(By.CSS_SELECTOR, 'dd[data-fact="state"]').text
    wait.until(ec.element_to_be_clickable((By.ID, "cancel"))).click()
    wait.until(ec.alert_is_present())
    driver.switch_to.alert.accept()
    wait.until(ec.text_to_be_present_in_element((By.ID, "action-result"), "cancelled"))
    wait.until(ec.text_to_be_present_in_element((By.CSS_SELECTOR, 'dd[data-fact="state"]'), "cancelled"))
    report["cancelled"] = True
except Exception as e:  # noqa: BLE001 - any failure is reported with the page's state
    fail("%s: %s (report so far: %s)" % (type(e).__name__, e, json.dumps(report)), driver)

print(json.dumps(report))
driver.quit()
