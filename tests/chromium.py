"""Flags shared by the browser tests: Debian's chromium, headless, offline.

Software WebGL (swiftshader), no first-run or background traffic, and every
request outside the machine sent to a dead proxy (port 9), so that a page
that reached for the network would fail visibly. Each test adds its own
(profile folder, resolver rules, window size, ...).
"""

OFFLINE_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",  # software WebGL without the deprecation warning
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--proxy-server=127.0.0.1:9",
]
