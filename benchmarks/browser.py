"""The headless Chromium the browser benchmarks drive: Debian's binary (never a downloaded
one) with software WebGL, and a wait for two drawn frames."""

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--disable-gpu", "--use-gl=swiftshader", "--enable-unsafe-swiftshader",
        "--disable-background-networking", "--disable-component-update", "--disable-sync",
        "--no-first-run"]
FRAMES_JS = """() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))"""
