"""plenodecode.report"""
