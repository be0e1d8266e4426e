"""``python3 -m tiago_nav.nodes``: rewrite ``config/*.yaml`` from the nodes' parameter
dataclasses (run it after changing a default; test/unit/test_params.py checks they agree)."""
import os
import sys

from tiago_nav.nodes import CONFIG_FILES, config_text

CONFIG = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..', 'config')

if __name__ == '__main__':
    names = sys.argv[1:] or list(CONFIG_FILES)
    texts = {name: config_text(name) for name in names}    # all of them before writing any:
    for name in names:                                     # a failing import leaves no file empty
        path = os.path.normpath(os.path.join(CONFIG, CONFIG_FILES[name]))
        with open(path, 'w') as f:
            f.write(texts[name])
        print('wrote', path)
