import sys

from bayes_sst.cli import main

sys.exit(main())
