"""The ending the house's checks share (tools/house_check.py, tools/commit_cites.py): one line per
finding, then a count line, and the exit status, 1 when there is any finding (a ctest test fails
on it) and 0 otherwise."""


def report(findings, summary):
    """Prints each finding and then summary; returns the exit status."""
    for line in findings:
        print(line)
    print(summary)
    return 1 if findings else 0
