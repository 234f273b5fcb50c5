"""What the live view's page (daemon/service/live_page.html) shows, read in a Browser
(cdp_browser.py): the state the page keeps in its body's data attributes, and its banner."""

BODY = "document.body.dataset"


def banner(b):
    """The banner as the reader sees it: its text and class, whether it takes room on the page,
    where it sits, when the page saw the failure and the remedy it names."""
    return b.js("(() => { const e = document.getElementById('banner'); const r = e.getBoundingClientRect();"
                " return { text: e.textContent, cls: e.className, shown: e.style.display !== 'none' && r.height > 0,"
                " top: r.top, when: document.getElementById('banner-when').textContent,"
                " remedy: document.getElementById('banner-remedy').textContent }; })()")
