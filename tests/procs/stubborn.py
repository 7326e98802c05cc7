"""Test process: ignores SIGINT and sleeps, so only SIGKILL can stop it."""

import signal
import time

signal.signal(signal.SIGINT, signal.SIG_IGN)
print("stubborn up", flush=True)
time.sleep(120)
