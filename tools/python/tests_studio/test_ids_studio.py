"""Servo Studio, issue 27, in a real headless Chromium against servo-sim: a bus with
three servos on ID 1 is listed by UID with the duplicates marked, *Separate* gives each a
free ID, and *Adopt* gives a replacement the silent expected ID."""


def id_rows(page):
    return [[td.text for td in tr.find_elements("css selector", "td")]
            for tr in page.all("#ids-table tbody tr")]


def test_duplicates_are_shown_and_separate_fixes_them(sim_factory, studio_factory, page):
    sim = sim_factory("1:foot", "1:foot", "1:arm", "2:wrist")
    p = page(studio_factory(sim.url).url)
    p.wait(lambda: p.text("scan-message") and "Scanning" not in p.text("scan-message")
           and p.by("#ids-list").is_enabled(), timeout=30, what="the start-up scan done")
    p.panel("scan")
    p.click("ids-list")
    rows = p.wait(lambda: len(id_rows(p)) == 4 and id_rows(p), what="4 servos by UID")
    assert sorted(r[1] for r in rows) == ["1", "1", "1", "2"]
    assert [r[5] for r in rows].count("DUPLICATE ID") == 3
    assert "ID 1 shared" in p.text("ids-message")
    p.click("ids-separate")
    rows = p.wait(lambda: "Separated" in p.text("ids-message") and id_rows(p),
                  timeout=30, what="the bus separated")
    assert sorted(int(r[1]) for r in rows) == [1, 2, 3, 4]
    assert all(r[5] == "ok" for r in rows)
    assert sorted(r[2] for r in rows) == ["arm", "foot", "foot", "wrist"]
    # the scan that follows sees four single servos
    p.wait_scanned(4, timeout=30)
    assert not p.text("scan-warning")


def test_adopt_gives_the_replacement_the_silent_id(sim_factory, studio_factory, page):
    sim = sim_factory("1:arm", "2:foot", "9:wrist")
    p = page(studio_factory(sim.url).url)
    p.wait_scanned(3)
    p.panel("scan")
    p.by("#adopt-expect").send_keys("1, 2, x")
    p.click("adopt-go")
    p.wait(lambda: "whole numbers" in (p.message() or ""), what="the form's refusal")
    p.by("#adopt-expect").clear()
    p.by("#adopt-expect").send_keys("1, 2, 3")
    p.click("adopt-go")
    p.wait(lambda: "is now ID 3" in p.text("ids-message"), timeout=30, what="the adoption")
    rows = id_rows(p)
    assert sorted((r[1], r[2]) for r in rows) == [("1", "arm"), ("2", "foot"), ("3", "wrist")]
    p.wait(lambda: sorted(r[0] for r in p.scan_rows()) == ["1", "2", "3"], timeout=30,
           what="the scan after the adoption")
