"""The fuzz tier prints its outcomes per input kind at the end of the run."""

from .harness import print_counts


def pytest_terminal_summary(terminalreporter, config):
    text = print_counts()
    if text:
        terminalreporter.write_line("fuzz outcomes per input kind:\n" + text)
