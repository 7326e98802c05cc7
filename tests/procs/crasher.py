"""Test process: prints a line, then exits with the code given (after a short delay)."""

import sys
import time

print(f"crasher up, will exit {sys.argv[1]}", flush=True)
time.sleep(float(sys.argv[2]) if len(sys.argv) > 2 else 0.1)
sys.exit(int(sys.argv[1]))
