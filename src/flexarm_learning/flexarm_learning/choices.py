"""What an accuracy study may be asked, declared once for the core and the command line: the
kinds of model (:mod:`.arm_error`), the default one, the splits and the learning curve's
training sizes. Light on purpose: ``flexarm``'s argument parser reads it without importing
Pinocchio."""

KINDS = ('rigid', 'geometric', 'elastostatic', 'greybox', 'gp', 'mlp', 'auto')
AUTO_CANDIDATES = ('elastostatic', 'greybox', 'gp', 'mlp')     # what ``auto`` chooses among
DEFAULT_KIND = 'greybox'
SPLITS = 3
LEARNING_CURVE = (10, 20, 40, 80, 160)
